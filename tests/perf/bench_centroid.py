"""Speed and accuracy benchmark of calibration.centroid.find_spot against the full-frame thesis reference.

Run from anywhere:  /work/main/.venv/bin/python tests/perf/bench_centroid.py [--frames 200] [--seconds 2]

Renders 640×480 uint16 frames with the renderer of tests/calibration/test_centroid.py (r = 4.64 px pinhole sun
spot, σ = 0.5 px blur, 800 DN on 20 DN, Poisson + 3 DN read noise, 10-bit clip) plus 20 full-scale hot pixels
each, on one core (cv2.setNumThreads(1)). The frames (~120 MB) do not fit in the CPU caches, as for frames
streaming from a camera. Targets: find_spot >= 3000 frames/s and >= 50× the reference. Exit status 1 if a
target is missed. Not collected by pytest (the file name does not start with test_).
"""

from __future__ import annotations

import argparse
import importlib.util
import sys
import time
from pathlib import Path

import cv2
import numpy as np

REPO = Path(__file__).resolve().parents[2]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

from calibration.centroid import centroid_reference, find_spot  # noqa: E402
from calibration.design import SensorDesign  # noqa: E402

TARGET_FPS = 3000.0
TARGET_SPEEDUP = 50.0


def _renderer():
    """The spot renderer of the unit tests (same spots as the tests and the find_spot docstring numbers)."""
    path = REPO / "tests" / "calibration" / "test_centroid.py"
    spec = importlib.util.spec_from_file_location("_centroid_test_render", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _rms(est: np.ndarray, truth: np.ndarray) -> tuple[float, float, float]:
    """Radial RMS, per-axis RMS and max radial error [px]."""
    err = est - truth
    radial = np.hypot(err[:, 0], err[:, 1])
    return float(np.sqrt(np.mean(radial ** 2))), float(np.sqrt(np.mean(err ** 2))), float(radial.max())


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=200, help="number of different frames [default 200]")
    ap.add_argument("--seconds", type=float, default=2.0, help="minimum timing per method [s, default 2]")
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args(argv)

    cv2.setNumThreads(1)  # one core, as the target says (the library itself never touches this)
    sat = SensorDesign().saturation_dn
    r = _renderer()
    rng = np.random.default_rng(args.seed)
    n = args.frames
    truth = np.column_stack([rng.uniform(20, 620, n), rng.uniform(20, 460, n)])
    frames = []
    for x, y in truth:
        f = r.render_spot(x, y, rng=rng)
        f.flat[rng.integers(0, f.size, 20)] = sat  # hot pixels
        frames.append(f)
    h, w = frames[0].shape
    print(f"{n} frames {w}x{h} {frames[0].dtype}, spot r = {r.SPOT_RADIUS_PX:.2f} px, 20 hot px each; "
          f"OpenCV {cv2.__version__}, {cv2.getNumThreads()} thread")

    # --- find_spot: repeat the whole set until >= args.seconds
    for f in frames[:20]:
        find_spot(f, saturation_dn=sat)  # warm-up
    calls = 0
    t0 = time.perf_counter()
    while True:
        for f in frames:
            find_spot(f, saturation_dn=sat)
        calls += n
        dt = time.perf_counter() - t0
        if dt >= args.seconds:
            break
    fps_fast = calls / dt

    # --- reference: as many frames as fit in args.seconds (at least 20)
    ref_est = []
    t0 = time.perf_counter()
    for f in frames:
        ref_est.append(centroid_reference(f))
        dt_ref = time.perf_counter() - t0
        if len(ref_est) >= 20 and dt_ref >= args.seconds:
            break
    fps_ref = len(ref_est) / dt_ref
    speedup = fps_fast / fps_ref

    fast_est = np.array([find_spot(f, saturation_dn=sat).xy for f in frames])
    thesis_est = np.array([find_spot(f, saturation_dn=sat, weighting="eq5").xy for f in frames])
    m = len(ref_est)
    print(f"\nfind_spot           {fps_fast:9.0f} frames/s  ({1e3 / fps_fast:.3f} ms/frame, {calls} calls)")
    print(f"centroid_reference  {fps_ref:9.1f} frames/s  ({1e3 / fps_ref:.1f} ms/frame, {m} frames)")
    print(f"speed-up            {speedup:9.0f}x")

    print("\naccuracy vs rendered truth [px]         radial RMS  per-axis RMS  max radial")
    rows = [("find_spot (default)", fast_est, truth),
            ("find_spot weighting='eq5' (thesis)", thesis_est, truth),
            ("find_spot default, same frames as ref", fast_est[:m], truth[:m]),
            ("centroid_reference (full frame)", np.array(ref_est), truth[:m])]
    for name, est, tr in rows:
        rad, axis, mx = _rms(est, tr)
        print(f"  {name:38s} {rad:9.4f}  {axis:12.4f}  {mx:10.4f}")
    agree = np.abs(thesis_est[:m] - np.array(ref_est)).max()
    print(f"  max |find_spot eq5 - reference| = {agree:.2e} px")

    print("\nweighting / filtering options on the same frames (per-axis RMS [px]; noise-free = method bias)")
    clean = [r.render_spot(x, y) for x, y in truth[:100]]
    for wt, fl in [("threshold-subtracted", "outliers"), ("background-subtracted", "outliers"),
                   ("eq5", "outliers"), ("threshold-subtracted", "median"), ("eq5", "median")]:
        noisy = np.array([find_spot(f, saturation_dn=sat, weighting=wt, filtering=fl).xy for f in frames])
        free = np.array([find_spot(f, saturation_dn=sat, weighting=wt, filtering=fl).xy for f in clean])
        print(f"  {wt:22s} {fl:9s} noisy {_rms(noisy, truth)[1]:.4f}   noise-free {_rms(free, truth[:100])[1]:.4f}"
              f" (max {_rms(free, truth[:100])[2]:.4f})")

    ok_fps = fps_fast >= TARGET_FPS
    ok_speedup = speedup >= TARGET_SPEEDUP
    print(f"\ntarget >= {TARGET_FPS:.0f} frames/s: {'MET' if ok_fps else 'MISSED'} ({fps_fast:.0f})")
    print(f"target >= {TARGET_SPEEDUP:.0f}x reference: {'MET' if ok_speedup else 'MISSED'} ({speedup:.0f}x)")
    return 0 if ok_fps and ok_speedup else 1


if __name__ == "__main__":
    sys.exit(main())
