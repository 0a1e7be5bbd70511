#!/usr/bin/env bash
# `obscura render` under mpirun (docs/mpi.md): for every technique with a CPU backend, 2 ranks (and
# 3 for those split per pixel) write the same EXR and PNG bytes as one process; the techniques
# that render per pixel are split, the others rendered by rank 0 alone with a warning; a rank that
# dies mid-render makes mpirun exit non-zero by itself, naming the rank. Data-parallel renders
# (--distribute data) of volumes come close to one process's image with ghost zones, and visibly
# further without them.
set -u
cli=$1 root=$2 out=$3 metrics=$4
pass=0 fail=0
check() { # description, command...
  local d=$1; shift
  if "$@"; then pass=$((pass + 1)); echo "ok: $d"; else fail=$((fail + 1)); echo "FAIL: $d"; fi
}
not() { ! "$@"; }
if ! command -v mpirun >/dev/null; then
  echo "FAIL: mpirun not found (Debian: openmpi-bin; scripts/setup.sh installs it)"
  exit 1
fi
rm -rf "$out" && mkdir -p "$out"
# Tests run as root in containers; Open MPI refuses root without both of these. Single copy
# through CMA needs ptrace rights containers often lack: plain shared memory serves as well.
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
mpirun=(mpirun --oversubscribe --allow-run-as-root --mca btl_vader_single_copy_mechanism none)
small=(--set /image/width=48 --set /image/height=32 --threads 1)
# Techniques that must be split: they render through the per-pixel driver.
per_pixel="rt_ao obscurance path_trace"

# A bundled scene the technique renders (materials, lights, a volume...): the first that validates.
scene_for() {
  local t=$1 s
  for s in cornell_box sphere_on_plane volume_torus volume_torus_mesh sss_marble; do
    if "$cli" validate "$root/scenes/$s.json" --technique "$t" --backend cpu >/dev/null 2>&1; then
      echo "$root/scenes/$s.json"
      return
    fi
  done
}

# The files of dir a other than summary.json are in dir b with the same bytes.
same_files() {
  local f n=0
  for f in "$1"/*; do
    [ "$(basename "$f")" = summary.json ] && continue
    cmp -s "$f" "$2/$(basename "$f")" || { echo "  $(basename "$f") differs"; return 1; }
    n=$((n + 1))
  done
  [ "$n" -ge 2 ]
}

# The split render's summary: ranks, the same rays and statistics as one process, and whether the
# render was split (no "does not render per pixel" warning); prints "split" or "alone".
summary_of() { # one-process dir, split dir, ranks
  node -e "
    const fs = require('fs');
    const a = JSON.parse(fs.readFileSync('$1/summary.json'));
    const b = JSON.parse(fs.readFileSync('$2/summary.json'));
    const alone = b.warnings.some(w => /does not render per pixel/.test(w));
    const ok = b.ranks === $3 && a.ranks === undefined && b.rays === a.rays &&
      JSON.stringify(a.outputs) === JSON.stringify(b.outputs) && b.nan_count === a.nan_count;
    if (!ok) { console.error('summary differs', a.rays, b.rays, b.ranks); process.exit(1); }
    console.log(alone ? 'alone' : 'split');"
}

techniques=$("$cli" techniques | node -e "
  const t = JSON.parse(require('fs').readFileSync(0));
  console.log(t.filter(x => x.backends.includes('cpu')).map(x => x.name).join(' '));")
check "the registry lists CPU techniques" test -n "$techniques"
# The sanitizer builds (OBS_TEST_SANITIZED=1) run the split and the alone paths once each (every
# per-pixel technique goes through the same tile queue, every other through the same warning) and
# one volume: the MPI code is the same for each, and the release build runs them all.
volumes="volume_torus volume_engine"
if [ "${OBS_TEST_SANITIZED:-0}" = 1 ]; then
  techniques=$(for t in $techniques; do case $t in rt_ao | ssao) echo "$t" ;; esac; done)
  volumes=volume_torus
  echo "note: sanitizer build: MPI renders of $(echo $techniques) and $volumes only"
fi
for t in $techniques; do
  scene=$(scene_for "$t")
  if [ -z "$scene" ]; then
    check "$t: a bundled scene renders it" false
    continue
  fi
  d=$out/$t
  "$cli" render "$scene" --technique "$t" --backend cpu -o "$d/one" "${small[@]}" --quiet \
    >"$d.one.log" 2>&1
  check "$t: one process renders" test $? -eq 0
  for np in 2 3; do
    timeout -k 5 120 "${mpirun[@]}" -np "$np" "$cli" render "$scene" --technique "$t" \
      --backend cpu -o "$d/np$np" "${small[@]}" >"$d.np$np.log" 2>&1
    check "$t: $np ranks render" test $? -eq 0
    check "$t: $np ranks write the same bytes as one process" same_files "$d/one" "$d/np$np"
    how=$(summary_of "$d/one" "$d/np$np" "$np")
    check "$t: $np ranks: summary says ranks $np, same rays and statistics" test -n "$how"
    if [ "$how" = alone ]; then
      check "$t: not per pixel: rank 0 says it rendered alone" \
        grep -q "warning: technique \"$t\" on the cpu backend does not render per pixel" \
        "$d.np$np.log"
      break # a render rank 0 does alone needs no third rank
    fi
    check "$t: $np ranks: rank 0 reports the ranks" grep -q " on $np ranks," "$d.np$np.log"
    check "$t: $np ranks: every rank renders per pixel" \
      not grep -q "judged the run not per pixel" "$d.np$np.log"
  done
  case " $per_pixel " in
    *" $t "*) check "$t: renders per pixel, so it is split" test "$how" = split ;;
  esac
done

# A rank that dies mid-render (the test hook aborts it after its first tile) ends the job: mpirun
# exits non-zero, names the rank, and no rank is left waiting for it. Open MPI 4.1's mpirun can
# (rarely) deadlock in its own PMIx finalize after every rank is gone; what is tested is the ranks,
# so that case (killed by the timeout, after it reported the death) passes with a note.
no_rank_left() { ! pgrep -f -- "-o $1 " >/dev/null; }
for ar in 1 0; do
  d=$out/abort$ar
  # 96 tiles, so that every rank gets some however late it starts on a busy machine.
  OBSCURA_MPI_TEST_ABORT_RANK=$ar timeout -k 5 30 "${mpirun[@]}" -np 3 "$cli" render \
    "$root/scenes/sphere_on_plane.json" -o "$d" --set /image/width=192 --set /image/height=128 \
    --threads 1 >"$d.log" 2>&1
  rc=$?
  [ "$rc" -eq 124 ] || [ "$rc" -eq 137 ] && echo "note: mpirun hung after the ranks ended (rc $rc)"
  check "rank $ar aborted: mpirun exits non-zero ($rc)" test "$rc" -ne 0
  check "rank $ar aborted: the hook said so" \
    grep -q "rank $ar: aborting .*OBSCURA_MPI_TEST_ABORT_RANK" "$d.log"
  check "rank $ar aborted: mpirun names the rank" \
    grep -q "process rank $ar .* exited on signal 6" "$d.log"
  check "rank $ar aborted: nothing written" test ! -e "$d/ao.exr"
  check "rank $ar aborted: no rank left running" no_rank_left "$d"
done

# Started by mpirun alone, a render is one process's: no split, no warning, no "ranks".
scene=$(scene_for rt_ao)
timeout -k 5 60 "${mpirun[@]}" -np 1 "$cli" render "$scene" --technique rt_ao --backend cpu \
  -o "$out/np1" "${small[@]}" >"$out/np1.log" 2>&1
check "1 rank renders" test $? -eq 0
check "1 rank writes what one process does" same_files "$out/rt_ao/one" "$out/np1"
check "1 rank says nothing of ranks" bash -c "! grep -q ranks '$out/np1/summary.json'"

# Data-parallel (--distribute data): each rank renders one brick of the volumes over the whole
# image and rank 0 composites them by depth. At one sample per pixel the nearest brick's pixel is
# copied, so the composite differs from one process only where a camera ray's march restarts at a
# seam between bricks (its half-voxel steps start there, the whole render's at the volume's face):
# a thin feature may be caught by one and missed by the other, so a few pixels may differ. Alpha
# may differ in at most 3 of the 3072 pixels, AO (by more than 1e-3) in at most 6, AO and final
# RMSE at most 0.02 (one pixel off by 1 gives 0.018); measured: none, final RMSE below 4e-6.
# Without ghost zones the AO march reads nothing past a seam, so AO must be off in at least 0.3 %
# of the pixels and 3 times as many (measured 0.5-4.8 %: hits near a seam lose occluders).
# Figures from metrics_tool: "<channel> rmse=R max_abs=M differ=F".
figure() { # metrics line, key
  sed -n "s/.* $2=\([^ ]*\).*/\1/p" <<<"$1"
}
below() { awk -v a="$1" -v b="$2" 'BEGIN { exit !(a + 0 <= b + 0) }'; }
# An AO reach of 0.15 (of the longest side) keeps each brick well short of the whole volume.
vol=(--set /image/width=64 --set /image/height=48 --set /technique/params/max_distance=0.15
     --threads 1 --quiet)
mkdir -p "$out/data"
for s in $volumes; do
  d=$out/data/$s
  "$cli" render "$root/scenes/$s.json" -o "$d/one" "${vol[@]}" >"$d.one.log" 2>&1
  check "data $s: one process renders" test $? -eq 0
  for np in 2 3; do
    for g in ghost noghost; do
      flags=(--distribute data)
      [ "$g" = noghost ] && flags+=(--no-ghost)
      timeout -k 5 120 "${mpirun[@]}" -np "$np" "$cli" render "$root/scenes/$s.json" \
        -o "$d/$g$np" "${vol[@]}" "${flags[@]}" >"$d.$g$np.log" 2>&1
      check "data $s: $np ranks ($g) render" test $? -eq 0
    done
    check "data $s: $np ranks write the files one process does" \
      test "$(ls "$d/one")" = "$(ls "$d/ghost$np")"
    check "data $s: $np ranks: summary says ranks $np" grep -q "\"ranks\": $np" \
      "$d/ghost$np/summary.json"
    m=$("$metrics" diff "$d/ghost$np/final.exr" "$d/one/final.exr" ao alpha final.G)
    n=$("$metrics" diff "$d/noghost$np/final.exr" "$d/one/final.exr" ao)
    echo "data $s, $np ranks, ghost: $(tr '\n' ' ' <<<"$m")"
    echo "data $s, $np ranks, no ghost: $n"
    ao=$(figure "$(grep '^ao ' <<<"$m")" rmse) aod=$(figure "$(grep '^ao ' <<<"$m")" differ)
    aod0=$(figure "$n" differ)
    check "data $s: $np ranks: alpha as one process's but at most 3 pixels" \
      below "$(figure "$(grep '^alpha ' <<<"$m")" differ)" 0.001
    check "data $s: $np ranks: AO off in at most 6 pixels ($aod)" \
      below "$aod" 0.002
    check "data $s: $np ranks: AO RMSE $ao <= 0.02" below "$ao" 0.02
    check "data $s: $np ranks: final RMSE <= 0.02" \
      below "$(figure "$(grep '^final.G ' <<<"$m")" rmse)" 0.02
    check "data $s: $np ranks: no ghost zones: AO off in more pixels ($aod0 >= 0.003, 3 x $aod)" \
      bash -c "awk -v a=$aod -v b=$aod0 'BEGIN { exit !(b >= 0.003 && b >= 3 * a) }'"
  done
done
# Partial coverage (4 samples per pixel) composites with "over": close, not exact.
d=$out/data/spp4
"$cli" render "$root/scenes/volume_torus.json" -o "$d/one" "${vol[@]}" --set /image/spp=4 \
  >"$d.one.log" 2>&1
timeout -k 5 120 "${mpirun[@]}" -np 2 "$cli" render "$root/scenes/volume_torus.json" \
  -o "$d/np2" "${vol[@]}" --set /image/spp=4 --distribute data >"$d.np2.log" 2>&1
check "data spp 4: 2 ranks render" test $? -eq 0
m=$("$metrics" diff "$d/np2/final.exr" "$d/one/final.exr" ao alpha)
echo "data spp 4, 2 ranks: $(tr '\n' ' ' <<<"$m")"
check "data spp 4: AO and alpha RMSE <= 0.03" below "$(figure "$m" rmse | sort -g | tail -1)" 0.03
# What cannot render bricks refuses, before any rank renders: bad input, said once.
timeout -k 5 60 "${mpirun[@]}" -np 2 "$cli" render "$root/scenes/sphere_on_plane.json" \
  -o "$out/data/refused" "${small[@]}" --distribute data >"$out/data/refused.log" 2>&1
check "data: a technique without volumes exits 2" test $? -eq 2
check "data: ... saying why, once" \
  test "$(grep -c 'renders no volumes' "$out/data/refused.log")" -eq 1
"$cli" render "$root/scenes/volume_torus.json" -o "$out/data/vk" "${small[@]}" \
  --distribute data --backend vulkan >"$out/data/vk.log" 2>&1
check "data: the vulkan backend is refused (exit 2)" test $? -eq 2
check "data: ... saying so" grep -q "cpu backend only" "$out/data/vk.log"

echo "$pass passed, $fail failed"
[ "$fail" -eq 0 ]
