// "Clone": the single-job submit form filled from an existing job's document
// (GET /api/v1/jobs/{id}/document): its bundled scene and image size, or the inline document
// pasted; its technique, backend and every parameter it ran with; its label and priority.
import {api, el} from './api.js';

/** What a parameter control shows for value v (selects hold JSON, text fields the plain value). */
const shown = (p, v) => (p.choices || typeof v !== 'string' ? JSON.stringify(v) : v);

/**
 * Fills the form's controls `c` ({form, sceneSel, sceneJson, width, height, priority, label,
 * block, showSource}) from job `id`; a note above the form says where the values came from.
 */
export async function prefillClone(id, c) {
  const note = el('p', {className: 'clone-note', role: 'status'}, `Loading job ${id}…`);
  c.form.prepend(note);
  let r;
  try {
    r = await api(`/api/v1/jobs/${id}/document`);
  } catch (e) {
    note.className = 'clone-note error';
    note.textContent = `Cannot clone job ${id}: ${e.message}`;
    return;
  }
  const doc = r.document || {};
  const tech = doc.technique || {};
  const bundled = [...c.sceneSel.options].some((o) => o.value === r.scene);
  c.form.querySelector(`input[name=source][value=${bundled ? 'bundled' : 'paste'}]`).checked = true;
  c.showSource();
  if (bundled) {
    c.sceneSel.value = r.scene;
    if (doc.image) {
      c.width.value = String(doc.image.width);
      c.height.value = String(doc.image.height);
    }
  } else {
    const {technique, ...rest} = doc;
    c.sceneJson.value = JSON.stringify(rest, null, 2);
    // The clone keeps the inline scene's name (sent as scene_name with the pasted document).
    if (r.scene_name) c.form.dataset.sceneName = r.scene_name;
  }
  c.priority.value = String(r.priority);
  c.label.value = r.label || '';
  const b = c.block;
  if ([...b.technique.options].some((o) => o.value === tech.name)) {
    b.technique.value = tech.name;
    b.technique.dispatchEvent(new Event('change'));
    if (tech.backend && [...b.backend.options].some((o) => o.value === tech.backend)) b.backend.value = tech.backend;
    for (const p of b.params) {
      const v = (tech.params || {})[p.name];
      if (v !== undefined) p.control.value = shown(p, v);
    }
  }
  const what = bundled ? r.scene : `${r.scene_name || 'an inline scene'}, its document pasted`;
  note.textContent = `Filled from job ${id} (${what}): change what you need and submit a new job.`;
}
