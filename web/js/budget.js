// The budget question in the dashboard, and where each time came from: the submit form's
// time-budget job (technique "auto" with time_budget_ms), the comparison page's budget input with
// its "best under X ms" readout, the comparisons list's answer, a time-budget job's reasoning,
// and the device labels. What is best is the server's answer (docs/comparisons.md, "The answer"):
// these functions only show it.
import {api, el, fmtMs, fmtNum, paramText} from './api.js';

/** A time's device in words, as the server labels it ("vulkan · llvmpipe (…) (software)"). */
export const deviceText = (device) => (device && device.label) || 'device unknown';

/** The distinct device labels of a comparison's candidates, one per backend and device. */
export function deviceLabels(cands) {
  return [...new Set((cands || []).map((c) => c.device && c.device.label).filter(Boolean))];
}

const pickText = (p) => `#${p.index} ${p.technique}/${p.backend} ${paramText(p.params)}: ${fmtMs(p.time_ms)} ms, ` +
  `RMSE ${fmtNum(p.rmse, 3)}${p.at_reference_accuracy ? ' (at reference accuracy)' : ''}`;

/**
 * A comparison's answer as lines, one per reference (candidates measured against different
 * references are not ranked together): its best candidate and, with a budget, the best within it.
 */
export function answerLines(answer, {short = false} = {}) {
  if (!answer || !answer.groups || !answer.groups.length) return [];
  const many = answer.groups.length > 1;
  return answer.groups.map((g) => {
    const head = many ? `${g.reference || `reference job ${g.reference_job_id}`}${g.label ? ` (${g.label})` : ''}: ` : '';
    if (!g.best) return `${head}no candidate measured yet`;
    const best = `best ${pickText(g.best)}`;
    if (answer.budget_ms === null || answer.budget_ms === undefined) return head + best;
    const under = g.best_under_budget
      ? `best under ${fmtMs(answer.budget_ms)} ms ${pickText(g.best_under_budget)}`
      : `none of ${g.measured} fits ${fmtMs(answer.budget_ms)} ms`;
    return short && g.best_under_budget && g.best_under_budget.index === g.best.index
      ? `${head}${best} (also best under ${fmtMs(answer.budget_ms)} ms)` : `${head}${best}; ${under}`;
  });
}

/** The comparisons list's cell: each comparison's answer without opening it. */
export function answerCell(c) {
  const lines = answerLines(c.answer, {short: true});
  return el('td', {className: 'answer'}, lines.length ? el('ul', {className: 'plain'}, ...lines.map((l) => el('li', {}, l))) : '–');
}

/**
 * The comparison page's budget panel: a time budget in ms (the request's budget_ms to start with)
 * and the readout "best under X ms" per reference, from GET /api/v1/comparisons/{id}?budget_ms=X.
 * onBudget(ms or null) lets the chart draw its line.
 */
export function budgetPanel(id, initial, onBudget) {
  const input = el('input', {type: 'number', id: 'budget-ms', min: '0', step: 'any', inputMode: 'decimal',
                             value: Number.isFinite(initial) ? String(initial) : '', 'aria-describedby': 'budget-desc'});
  const out = el('output', {className: 'budget-readout', for: 'budget-ms', 'aria-live': 'polite'});
  const panel = el('div', {className: 'budget'},
    el('label', {for: 'budget-ms'}, 'Time budget (ms) '), input,
    el('small', {id: 'budget-desc', className: 'desc'}, ' the most accurate candidate whose median total time fits, per reference ' +
      '(candidates measured against different references are not ranked together); the chart marks the budget with a vertical line.'),
    out);
  let asked = 0;
  const show = async () => {
    const v = Number(input.value);
    const ms = input.value.trim() !== '' && Number.isFinite(v) && v > 0 ? v : null;
    input.setCustomValidity(input.value.trim() === '' || ms ? '' : 'a time above 0');
    onBudget(ms);
    const mine = ++asked;
    try {
      const c = await api(`/api/v1/comparisons/${id}${ms ? `?budget_ms=${ms}` : ''}`);
      if (mine !== asked) return;
      const lines = answerLines(c.answer);
      out.replaceChildren(...(lines.length ? lines : ['No candidate measured yet.']).map((l) => el('div', {}, l)));
    } catch (e) {
      if (mine === asked) out.textContent = e.message;
    }
  };
  input.addEventListener('change', show);
  return {node: panel, refresh: show, value: () => (Number(input.value) > 0 ? Number(input.value) : null)};
}

// ---- the submit form -----------------------------------------------------------------------------

/** The form's fields of a time-budget job: the budget, and what auto picks from. */
export function budgetFields() {
  const input = el('input', {type: 'number', id: 'time-budget-ms', min: '0', step: 'any', value: '200'});
  input.dataset.pointer = '/time_budget_ms';
  const err = el('span', {id: 'time-budget-ms-err', className: 'field-error'});
  input.setAttribute('aria-describedby', 'time-budget-ms-desc time-budget-ms-err');
  input._err = err;
  const node = el('fieldset', {className: 'budget-fields'}, el('legend', {}, 'Technique: auto (fastest within a time budget)'),
    el('div', {className: 'field'}, el('label', {for: 'time-budget-ms'}, 'Time budget (ms)'), input,
      el('small', {id: 'time-budget-ms-desc', className: 'desc'},
        'auto picks from the comparison candidates this server has measured on this scene (or, when none, on scenes within 2× its ' +
        'pixel count), on the devices it runs now (Vulkan timings only of its own device kind): of those whose median total time fits ' +
        'the budget, the most accurate (AO RMSE against their reference); equally accurate ones within the reference\'s noise go to ' +
        'the faster. Nothing measured or nothing fitting is refused with the reason. ',
        el('a', {href: '#/comparisons'}, 'The comparisons it reads.')), err));
  return {node, input};
}

/** The body of a time-budget job, or an error for the budget field. */
export function readBudget(input, base) {
  const v = Number(input.value);
  if (input.value.trim() === '' || !Number.isFinite(v) || !(v > 0)) return {error: 'a time in ms above 0'};
  if (!base.scene_file) return {error: 'auto picks for a bundled scene (its measured comparisons): choose one'};
  return {body: {...base, technique: 'auto', time_budget_ms: v}};
}

// ---- the job page --------------------------------------------------------------------------------

/** A time-budget job's reasoning: the pick's expected time and RMSE, the alternatives, and the actual time once it ran. */
export function choiceSection(j) {
  const c = j.choice;
  if (!c) return null;
  const actual = Number.isFinite(c.actual_ms)
    ? `ran in ${fmtMs(c.actual_ms)} ms (median of its timed renders) against ${fmtMs(c.expected_ms)} ms expected: ` +
      `${(c.actual_ms / c.expected_ms).toPrecision(3)}×${c.actual_ms > c.budget_ms ? `, over the ${fmtMs(c.budget_ms)} ms budget` : ''}`
    : 'has not run yet: its actual time appears here once it has.';
  return el('section', {className: 'choice', 'aria-labelledby': 'h-choice'},
    el('h2', {id: 'h-choice'}, 'Why this configuration (auto)'),
    el('p', {}, `Budget ${fmtMs(c.budget_ms)} ms. Picked ${c.technique} on ${c.backend} `, el('code', {}, paramText(c.params)),
      `: expected ${fmtMs(c.expected_ms)} ms with RMSE ${fmtNum(c.expected_rmse, 3)} (comparison `,
      el('a', {href: `#/comparisons/${c.comparison_id}`}, String(c.comparison_id)), `, candidate ${c.candidate}). `,
      `It ${actual}`),
    c.reference_label ? el('p', {}, `Every RMSE weighed here is measured against ${c.reference_label}` +
      (c.other_references ? `; ${c.other_references} measured against other references were left out, since errors against different references are not comparable.` : '.')) : null,
    el('p', {className: 'muted'}, `${c.reason}. Read from ${c.from}; ${c.considered} configuration${c.considered === 1 ? '' : 's'} considered` +
      `${c.vulkan_kind ? `, Vulkan timings of ${c.vulkan_kind} devices only` : ', CPU timings only (no Vulkan lane)'}.`),
    c.alternatives && c.alternatives.length ? el('table', {className: 'alternatives'},
      el('caption', {}, 'Alternatives considered (by RMSE)'),
      el('thead', {}, el('tr', {}, ...['Technique', 'Backend', 'Parameters', 'Expected ms', 'Expected RMSE', 'Why not']
        .map((h) => el('th', {scope: 'col'}, h)))),
      el('tbody', {}, ...c.alternatives.map((a) => el('tr', {},
        el('td', {}, a.technique), el('td', {}, a.backend), el('td', {}, el('code', {}, paramText(a.params))),
        el('td', {className: 'num'}, fmtMs(a.expected_ms)), el('td', {className: 'num'}, fmtNum(a.expected_rmse, 3)),
        el('td', {}, a.why_not))))) : null);
}
