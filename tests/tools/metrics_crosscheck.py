"""Cross-checks obscura's comparison metrics (obs_metrics_compare) against OpenImageIO's idiff and
oiiotool, against numpy, and its SSIM against scikit-image's structural_similarity, on image pairs
written by metrics_tool and on two small real renders (rt_ao and ssao of the Cornell box).

Usage: metrics_crosscheck.py METRICS_TOOL WORK_DIR OBSCURA SCENE
       (run through metrics_crosscheck.sh)

For every pair:
  * obscura: `metrics_tool compare` (reads the files back, prints full-precision numbers);
  * OpenImageIO: `idiff -v` (RMS error, Peak SNR, Max error) and `oiiotool A B --sub --printstats`
    (mean and extremes of the signed difference). idiff prints 6 significant digits (%g) and
    printstats 6 decimals (%f), which sets the tolerances below. Masks: both images are multiplied
    by the mask with oiiotool first, so uncovered pixels contribute 0, and the whole-image values
    are rescaled to the covered pixels (RMS by sqrt(N/n), PSNR by -10 log10(N/n), mean by N/n);
  * numpy: RMSE, bias, max |error| and PSNR recomputed from the pixels as OpenImageIO reads them
    (converted to uncompressed TIFF by oiiotool, so obscura's readers are not involved);
  * scikit-image: structural_similarity(a, b, gaussian_weights=True, sigma=1.5,
    use_sample_covariance=False, data_range=1) on those pixels in float64, the definition
    obs_metrics_ssim follows (with a mask: skimage's SSIM map, cropped as skimage crops it, averaged
    over the selected pixels). Images smaller than the 11x11 window: skimage refuses, obscura
    reports NaN.
Prints one table row per pair and exits 1 when anything disagrees.
"""
import math
import os
import re
import struct
import subprocess
import sys

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

PSNR_CAP = 100.0  # OBS_METRICS_PSNR_MAX

# idiff prints %g (6 significant digits: relative rounding <= 5e-6) of values it computes from
# float differences (exact for values within a factor 2, else rounded by <= 6e-8 relative).
TOL_IDIFF_REL = 1e-5
# oiiotool --printstats prints %f: 6 decimals, absolute rounding <= 5e-7 (then scaled by N/n).
TOL_STATS_ABS = 1e-6
# numpy sums the same float32 values in double, in another order: agreement to ~1e-13 expected.
TOL_NUMPY_REL = 1e-12
# SSIM: both in double from the same float32 values, the same filter and formula in another
# summation order: agreement to ~1e-15 expected; 1e-9 leaves room and still catches any
# definitional slip (window, sigma, border mode, crop, constants), which moves SSIM by > 1e-5.
TOL_SSIM_ABS = 1e-9


def run(*args):
    p = subprocess.run(args, capture_output=True, text=True)
    if p.returncode != 0:
        sys.exit(f"command failed ({p.returncode}): {' '.join(args)}\n{p.stdout}{p.stderr}")
    return p.stdout


def read_tiff(path):
    """Uncompressed single-channel striped TIFF of float32 or uint8 samples, as oiiotool writes it
    with `-d float|uint8 --compression none` (checked tag by tag, so a change of layout fails
    loudly). Returns the samples as stored."""
    with open(path, "rb") as f:
        raw = f.read()
    bo = {b"II": "<", b"MM": ">"}[raw[:2]]
    (ifd,) = struct.unpack(bo + "I", raw[4:8])
    (n,) = struct.unpack(bo + "H", raw[ifd:ifd + 2])
    tags = {}
    for i in range(n):
        tag, typ, cnt = struct.unpack(bo + "HHI", raw[ifd + 2 + 12 * i: ifd + 10 + 12 * i])
        fmt = {3: "H", 4: "I"}.get(typ)
        if fmt is None:
            continue
        size = struct.calcsize(fmt) * cnt
        if size <= 4:
            where = ifd + 10 + 12 * i
        else:
            (where,) = struct.unpack(bo + "I", raw[ifd + 10 + 12 * i: ifd + 14 + 12 * i])
        tags[tag] = struct.unpack(bo + fmt * cnt, raw[where:where + size])
    w, h = tags[256][0], tags[257][0]
    layout = {k: tags.get(k, (1,))[0] for k in (258, 259, 277, 284, 339, 274)}
    kinds = {(32, 3): bo + "f4", (8, 1): "u1"}
    dtype = kinds.get((layout[258], layout[339]))
    # uncompressed, one sample per pixel, contiguous planes, row 0 at the top
    plain = all(layout[k] == 1 for k in (259, 277, 284, 274))
    if dtype is None or not plain:
        sys.exit(f"{path}: unexpected TIFF layout {layout}")
    data = b"".join(raw[o:o + c] for o, c in zip(tags[273], tags[279]))
    return np.frombuffer(data, dtype=dtype, count=w * h).reshape(h, w)


def load(path, work, channel=None):
    """Pixels of `path` as OpenImageIO reads them (row 0 at the top), via an uncompressed TIFF, in
    double. 8-bit PNG codes are converted the way obs_image_read_png documents, float32(code)/255
    in float32: OpenImageIO's own 8-bit-to-float conversion differs from it by up to one float ulp,
    a reader difference that is no business of the metrics."""
    png = path.endswith(".png")
    tif = os.path.join(work, os.path.basename(path) + (f".{channel}" if channel else "") + ".tif")
    pick = ["--ch", channel] if channel else []
    run("oiiotool", path, *pick, "-d", "uint8" if png else "float", "--compression", "none",
        "-o", tif)
    img = read_tiff(tif)
    if png:
        img = img.astype(np.float32) / np.float32(255.0)
    return img.astype(np.float64)


def check_corners(img, ours, path):
    """Both readers must agree on where row 0 is (and on the values themselves)."""
    got = tuple(np.float32(v) for v in (img[0, 0], img[0, -1], img[-1, 0]))
    # metrics_tool prints floats with %.9g, which round-trips float32 exactly.
    want = tuple(np.float32(ours[k]) for k in ("ref_top_left", "ref_top_right", "ref_bottom_left"))
    if got != want:
        sys.exit(f"{path}: corner values {got} as read by OpenImageIO differ from obscura's {want}")


def ssim_skimage(a, b, sel):
    """skimage's SSIM of candidate a against reference b (float64), averaged over the selected
    pixels of its cropped SSIM map; NaN where skimage refuses the size."""
    from skimage.metrics import structural_similarity
    if min(a.shape) < 11:
        return math.nan
    _, smap = structural_similarity(a, b, gaussian_weights=True, sigma=1.5,
                                    use_sample_covariance=False, data_range=1.0, full=True)
    pad = 5  # (win_size - 1) // 2, skimage's crop
    s, keep = smap[pad:-pad, pad:-pad], sel[pad:-pad, pad:-pad]
    return float(s[keep].mean()) if keep.any() else 1.0


def numpy_metrics(cand, ref, sel):
    d = (cand - ref)[sel]
    n = d.size
    mse = float(np.mean(d * d)) if n else 0.0
    return {
        "pixels": n,
        "rmse": math.sqrt(mse),
        "bias": float(d.mean()) if n else 0.0,
        "max_abs": float(np.abs(d).max()) if n else 0.0,
        "psnr": min(10 * math.log10(1 / mse), PSNR_CAP) if mse > 0 else PSNR_CAP,
        "ssim": ssim_skimage(cand, ref, sel),
    }


def number(text, pattern):
    m = re.search(pattern + r"\s*([-+0-9.einfa]+)", text)
    if not m:
        sys.exit(f"no match for {pattern!r} in:\n{text}")
    return float(m.group(1))


def idiff(a, b):
    """idiff's report (thresholds out of the way so it always passes)."""
    out = run("idiff", "-v", "-fail", "1e30", "-warn", "1e30", a, b)
    return {"rms": number(out, r"RMS error\s*="), "psnr": number(out, r"Peak SNR\s*="),
            "max": number(out, r"Max error\s*="), "mean_abs": number(out, r"Mean error\s*=")}


def printstats(a, b):
    """Statistics of the signed difference a - b."""
    out = run("oiiotool", a, b, "--sub", "--printstats")
    return {k.lower(): number(out, r"Stats " + k + ":") for k in ("Avg", "Min", "Max")}


failures = []
worst = {}  # what -> (largest |difference|, largest relative difference) over all pairs


def check(case, what, ours, theirs, tol_rel=0.0, tol_abs=0.0):
    diff = abs(ours - theirs)
    rel = diff / max(abs(ours), abs(theirs)) if diff else 0.0
    w = worst.get(what, (0.0, 0.0))
    worst[what] = (max(w[0], diff), max(w[1], rel))
    ok = diff <= tol_rel * max(abs(ours), abs(theirs)) + tol_abs
    if not ok:
        failures.append(f"{case}: {what}: obscura {ours!r} vs {theirs!r} "
                        f"(tolerance rel {tol_rel:g} abs {tol_abs:g})")
    return ok


def check_ssim(case, ours, theirs):
    if math.isnan(theirs):
        if not math.isnan(ours):
            failures.append(f"{case}: ssim: skimage refuses the size, obscura gives {ours!r}")
        return
    check(case, "ssim (skimage)", ours, theirs, 0.0, TOL_SSIM_ABS)


def real_renders(tool, work, obscura, scene):
    """SSIM of two small real renders of one scene (rt_ao and ssao AO, 64x48), both ways round.
    Both on the CPU: the images are what matters here, and the sanitizer build runs this test
    without the Vulkan driver's leak suppressions."""
    dirs = {}
    for tech in ("rt_ao", "ssao"):
        d = os.path.join(work, "render_" + tech)
        run(obscura, "render", scene, "-o", d, "--quiet", "--technique", tech, "--backend", "cpu",
            "--set", "/image/width=64", "--set", "/image/height=48")
        dirs[tech] = os.path.join(d, "ao.exr")
    for cand, ref in (("ssao", "rt_ao"), ("rt_ao", "ssao")):
        ours = {}
        for line in run(tool, "compare", dirs[cand], dirs[ref], "--channel", "ao").splitlines():
            k, v = line.split("=", 1)
            ours[k] = float(v)
        a, b = load(dirs[cand], work, "ao"), load(dirs[ref], work, "ao")
        theirs = ssim_skimage(a, b, np.ones_like(b, dtype=bool))
        name = f"{cand}/{ref}"
        check_ssim(name, ours["ssim"], theirs)
        print(f"{name:<11} 64x48 render | ssim {ours['ssim']:.12f} skimage {theirs:.12f} "
              f"|diff| {abs(ours['ssim'] - theirs):.1e}")


def main():
    tool, work, obscura, scene = sys.argv[1:5]
    cases = [line.split() for line in run(tool, "gen", work).splitlines()]
    print(f"{'pair':<10} {'size':>6} {'pixels':>6} | {'obscura rmse':>13} {'idiff rms':>11} | "
          f"{'psnr':>9} {'idiff':>9} | {'max_abs':>10} {'idiff':>10} | {'bias':>11} "
          f"{'oiiotool':>10} | {'ssim':>10} {'skimage':>10} {'|diff|':>8}")
    for name, ext, has_mask in cases:
        cand = os.path.join(work, f"{name}_cand.{ext}")
        ref = os.path.join(work, f"{name}_ref.{ext}")
        mask = os.path.join(work, f"{name}_mask.exr") if has_mask == "1" else None
        ours = {}
        for line in run(tool, "compare", cand, ref, *([mask] if mask else [])).splitlines():
            k, v = line.split("=", 1)
            ours[k] = float(v)
        w, h = int(ours["width"]), int(ours["height"])

        # numpy on OpenImageIO's reading of the files.
        rimg = load(ref, work)
        check_corners(rimg, ours, ref)
        cimg = load(cand, work)
        sel = load(mask, work) > 0 if mask else np.ones_like(rimg, dtype=bool)
        npm = numpy_metrics(cimg, rimg, sel)
        check(name, "pixels (numpy)", ours["pixels"], npm["pixels"])
        for k in ("rmse", "bias", "max_abs", "psnr"):
            check(name, f"{k} (numpy)", ours[k], npm[k], TOL_NUMPY_REL, 1e-15)
        check_ssim(name, ours["ssim"], npm["ssim"])

        # OpenImageIO.
        a, b, scale = cand, ref, 1.0
        if mask:
            a = os.path.join(work, f"{name}_cand_masked.exr")
            b = os.path.join(work, f"{name}_ref_masked.exr")
            run("oiiotool", cand, mask, "--mul", "-d", "float", "-o", a)
            run("oiiotool", ref, mask, "--mul", "-d", "float", "-o", b)
            scale = (w * h) / ours["pixels"]
        di = idiff(a, b)
        st = printstats(a, b)
        rms = di["rms"] * math.sqrt(scale)
        psnr = di["psnr"] - 10 * math.log10(scale)
        bias = st["avg"] * scale
        ox = max(abs(st["min"]), abs(st["max"]))
        check(name, "rmse (idiff RMS error)", ours["rmse"], rms, TOL_IDIFF_REL)
        check(name, "max_abs (idiff Max error)", ours["max_abs"], di["max"], TOL_IDIFF_REL)
        check(name, "max_abs (oiiotool --sub min/max)", ours["max_abs"], ox, 0.0, TOL_STATS_ABS)
        check(name, "bias (oiiotool --sub Avg)", ours["bias"], bias, 0.0, TOL_STATS_ABS * scale)
        if ours["rmse"] == 0:
            # idiff: RMS 0 gives an infinite PSNR; obscura reports its finite cap.
            if not (math.isinf(psnr) and psnr > 0 and ours["psnr"] == PSNR_CAP):
                failures.append(f"{name}: identical pair: idiff PSNR {psnr}, "
                                f"obscura {ours['psnr']}")
        else:
            check(name, "psnr (idiff Peak SNR)", ours["psnr"], psnr, TOL_IDIFF_REL)
        print(f"{name:<10} {w:>3}x{h:<3} {int(ours['pixels']):>6} | {ours['rmse']:>13.9f} "
              f"{rms:>11.6g} | {ours['psnr']:>9.5f} {psnr:>9.6g} | {ours['max_abs']:>10.7f} "
              f"{di['max']:>10.6g} | {ours['bias']:>+11.8f} {bias:>+10.6f} | {ours['ssim']:>10.8f} "
              f"{npm['ssim']:>10.8f} {abs(ours['ssim'] - npm['ssim']):>8.1e}")
    real_renders(tool, work, obscura, scene)
    print("\nlargest differences over all pairs (absolute, relative):")
    for what, (diff, rel) in worst.items():
        print(f"  {what:<34} {diff:9.2e} {rel:9.2e}")
    if failures:
        print("\nFAILED:\n  " + "\n  ".join(failures))
        return 1
    print(f"\nall {len(cases)} pairs agree (idiff/oiiotool to their printed precision, numpy to "
          f"{TOL_NUMPY_REL:g} relative, SSIM to skimage within {TOL_SSIM_ABS:g})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
