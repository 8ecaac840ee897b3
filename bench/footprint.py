#!/usr/bin/env python3
"""Sparkle at any scale: how a gem's flakes hold up from thumbnail to close-up.

Measures the three figures of issue 27 with the release build of lapidary
(run with bench/.venv/bin/python: it reads EXRs with Mitsuba's Bitmap):

  scale        the mean colour of the fully-stone pixels of a small render
               against a big render of the same view box-filtered to the
               small size, per channel, over several seeds (target: within 1 %)
  convergence  RMSE over the stone's pixels (and over the whole image) at
               --spp against a long reference, at each --sizes, over
               --seeds render seeds (target: 2x lower than today)
  turntable    the stone's mean luminance over the frames of a turntable,
               and the standard deviation of its frame-to-frame change
               (target: a third of today's)
  look         converged renders of both modes against each other: the
               RMSE of footprints against flakes one by one (what the lobe
               changes in the picture, e.g. sparkle it smooths away) beside
               each mode's own noise, and a side-by-side PNG (--picture)
  lobe         the stone's mean with footprints (the default) over its mean
               with --exact-flakes (each flake by its own normal), over render seeds (a
               recipe file per population seed gives the spread of stones)

    bench/.venv/bin/python bench/footprint.py scale goldstone green-aventurine
    bench/.venv/bin/python bench/footprint.py convergence goldstone --sizes 64 128
    bench/.venv/bin/python bench/footprint.py turntable goldstone --frames 36
    bench/.venv/bin/python bench/footprint.py lobe pink-sunstone --size 16 --spp 1024
    bench/.venv/bin/python bench/footprint.py look goldstone --sizes 64 128 --picture look.png

Every render is a pure function of its settings, so a figure is the same on
every run; only the times vary. Extra render flags go after `--`, e.g.
`-- --bounces 2`; `-- --exact-flakes` shades every flake by its own normal
(footprints are the default), to compare.
"""
import argparse
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

from connections import load  # linear RGB and material_id of an EXR
ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BINARY = os.environ.get("LAPIDARY_BINARY", os.path.join(ROOT, "target", "release", "lapidary"))
# Rec. 709 luminance of linear RGB.
LUMINANCE = np.array([0.2126, 0.7152, 0.0722])


def render(gem, size, spp, seed, out, extra, frame=None):
    """Renders `gem` to the EXR `out`; returns the wall time in seconds."""
    command = [BINARY, "render", gem, "-q", "--size", str(size), "--spp", str(spp),
               "--seed", str(seed), "-o", out, *extra]
    if frame is not None:
        command += ["--frames", str(frame[1]), "--frame", str(frame[0])]
    started = time.perf_counter()
    subprocess.run(command, check=True)
    return time.perf_counter() - started


def box_filter(image, factor):
    """Mean over factor x factor blocks."""
    h, w = image.shape[:2]
    return image.reshape(h // factor, factor, w // factor, factor, *image.shape[2:]).mean(axis=(1, 3))


def scale(args, folder):
    factor = args.big // args.small
    if factor * args.small != args.big:
        sys.exit("--big must be a multiple of --small")
    print(f"| gem | seed | small {args.small} px, {args.spp} spp | big {args.big} px box-filtered "
          f"| stone pixels | difference R, G, B |")
    print("|---|---:|---|---|---:|---|")
    for gem in args.gems:
        worst = []
        for seed in range(1, args.seeds + 1):
            small_path = os.path.join(folder, f"small-{seed}.exr")
            big_path = os.path.join(folder, f"big-{seed}.exr")
            render(gem, args.small, args.spp, seed, small_path, args.extra)
            render(gem, args.big, args.big_spp, seed, big_path, args.extra)
            small, _ = load(small_path)
            big, big_material = load(big_path)
            # Fully stone: every sub-pixel of the big render sees a stone.
            stone = box_filter((big_material >= 2).astype(np.float64), factor) == 1.0
            small_mean = small[stone].mean(axis=0)
            big_mean = box_filter(big, factor)[stone].mean(axis=0)
            difference = small_mean / big_mean - 1.0
            worst.append(np.abs(difference).max())
            print(f"| {gem} | {seed} | {fmt(small_mean)} | {fmt(big_mean)} | {stone.sum()} "
                  f"| {', '.join(f'{100 * d:+.2f} %' for d in difference)} |")
        print(f"| {gem} | mean of the worst channel | | | | {100 * np.mean(worst):.2f} % "
              f"(max {100 * np.max(worst):.2f} %) |")


def convergence(args, folder):
    # A 16-spp glitter render's error is heavy-tailed (one binary, seeds 2
    # and 3: 0.78 and 0.33), so the RMSE is the root of the mean MSE over
    # --seeds render seeds (2, 3, …), the time their median.
    print(f"| gem | size | RMSE at {args.spp} spp vs {args.reference_spp} spp "
          f"({args.seeds} seeds) | whole image | median seed (stone) | time |")
    print("|---|---:|---:|---:|---:|---:|")
    for gem in args.gems:
        for size in args.sizes:
            reference_path = os.path.join(folder, f"reference-{size}.exr")
            test_path = os.path.join(folder, f"test-{size}.exr")
            render(gem, size, args.reference_spp, 1, reference_path, args.extra)
            reference, material = load(reference_path)
            mask = material >= 2
            stone, whole, seconds = [], [], []
            for seed in range(2, 2 + args.seeds):
                seconds.append(render(gem, size, args.spp, seed, test_path, args.extra))
                image, _ = load(test_path)
                stone.append(((image[mask] - reference[mask]) ** 2).mean())
                # The whole image holds what the stone's flakes send
                # elsewhere (the glossy floor's reflection of the stone).
                whole.append(((image - reference) ** 2).mean())
            print(f"| {gem} | {size} | {np.sqrt(np.mean(stone)):.5f} "
                  f"| {np.sqrt(np.mean(whole)):.5f} | {np.sqrt(np.median(stone)):.5f} "
                  f"| {np.median(seconds):.2f} s |")


def turntable(args, folder):
    print(f"| gem | frames | size | spp | render seed | mean luminance "
          f"| std of frame-to-frame change |")
    print("|---|---:|---:|---:|---:|---:|---:|")
    for gem in args.gems:
        runs = []
        for seed in range(1, args.seeds + 1):
            means = []
            for k in range(args.frames):
                # `--frame K` writes OUT-000K.exr beside OUT.exr.
                render(gem, args.size, args.spp, seed, os.path.join(folder, "frame.exr"),
                       args.extra, frame=(k, args.frames))
                image, material = load(os.path.join(folder, f"frame-{k:04d}.exr"))
                means.append((image[material >= 2] @ LUMINANCE).mean())
            runs.append(np.array(means))
            print(f"| {gem} | {args.frames} | {args.size} | {args.spp} | {seed} "
                  f"| {np.mean(means):.5f} | {np.std(np.diff(means)):.5f} |")
        if len(runs) > 1:
            # What the sampler adds: two seeds' frames differ by their noise
            # alone, so the frame-to-frame change's share from noise is
            # std(a − b) (a change holds two frames' noise, as a − b two
            # seeds'); the rest is the stone itself changing as it turns.
            noise = np.mean([np.std(a - b) for a, b in zip(runs, runs[1:])])
            change = np.mean([np.std(np.diff(r)) for r in runs])
            print(f"| {gem} | | | | noise part | | {noise:.5f} of {change:.5f} |")


def lobe(args, folder):
    print(f"| gem | size | spp | render seeds | footprints / flakes one by one (R, G, B) "
          f"| standard error | one render's spread |")
    print("|---|---:|---:|---:|---|---|---|")
    for gem in args.gems:
        means = {"exact": [], "footprints": []}
        for seed in range(1, args.seeds + 1):
            for mode, flags in (("exact", ["--exact-flakes"]), ("footprints", [])):
                path = os.path.join(folder, f"{mode}.exr")
                render(gem, args.size, args.spp, seed, path,
                       ["--threads", "1", *flags, *args.extra])
                image, material = load(path)
                means[mode].append(image[material >= 2].mean(axis=0))
        exact, footprints = np.array(means["exact"]), np.array(means["footprints"])
        ratio = footprints.mean(0) / exact.mean(0)
        # The ratio of means' standard error, paired over render seeds (delta method).
        paired = footprints / exact.mean(0) - exact * footprints.mean(0) / exact.mean(0) ** 2
        error = paired.std(0, ddof=1) / np.sqrt(len(exact))
        spread = exact.std(0, ddof=1) / exact.mean(0)
        print(f"| {gem} | {args.size} | {args.spp} | {args.seeds} | {fmt(ratio)} | {fmt(error)} "
              f"| {fmt(spread)} |")


def look(args, folder):
    print(f"| gem | size | spp | footprints vs flakes one by one (RMSE) | noise, flakes one by one "
          f"| noise, footprints |")
    print("|---|---:|---:|---:|---:|---:|")
    rows = []
    for gem in args.gems:
        for size in args.sizes:
            images = {}
            for mode, flags in (("exact", ["--exact-flakes"]), ("footprints", [])):
                for seed in (1, 2):
                    path = os.path.join(folder, f"{mode}-{seed}.exr")
                    render(gem, size, args.spp, seed, path, [*flags, *args.extra])
                    images[mode, seed] = load(path)
            stone = images["exact", 1][1] >= 2
            exact = (images["exact", 1][0] + images["exact", 2][0]) / 2
            footprints = (images["footprints", 1][0] + images["footprints", 2][0]) / 2

            def rmse(a, b):
                return np.sqrt(((a[stone] - b[stone]) ** 2).mean())

            # The noise of a two-seed mean: the RMS difference of the two
            # seeds is √2 σ, and the mean's noise σ/√2, so half of it.
            noise = {mode: rmse(images[mode, 1][0], images[mode, 2][0]) / 2
                     for mode in ("exact", "footprints")}
            print(f"| {gem} | {size} | {args.spp} | {rmse(footprints, exact):.4f} "
                  f"| {noise['exact']:.4f} | {noise['footprints']:.4f} |")
            scale = 256 // size
            rows.append(np.concatenate([np.kron(srgb8(image), np.ones((scale, scale, 1), np.uint8))
                                        for image in (images["exact", 1][0],
                                                      images["footprints", 1][0])], axis=1))
    if args.picture:
        import mitsuba as mi  # the venv's; Bitmap writes the PNG
        mi.set_variant("scalar_rgb")
        mi.Bitmap(np.concatenate(rows, axis=0)).write(args.picture)
        print(f"\nleft: flakes one by one, right: footprints; {args.picture}")


def srgb8(linear):
    """Linear RGB to 8-bit sRGB, clipped."""
    linear = np.clip(linear, 0.0, None)
    srgb = np.where(linear <= 0.0031308, 12.92 * linear, 1.055 * linear ** (1 / 2.4) - 0.055)
    return np.clip(np.round(srgb * 255), 0, 255).astype(np.uint8)


def fmt(rgb):
    return "(" + ", ".join(f"{c:.4f}" for c in rgb) + ")"


def main():
    argv = sys.argv[1:]
    extra = []
    if "--" in argv:
        extra = argv[argv.index("--") + 1:]
        argv = argv[:argv.index("--")]
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    commands = parser.add_subparsers(dest="command", required=True)
    s = commands.add_parser("scale", help="small render against a big one box-filtered")
    s.add_argument("gems", nargs="+")
    s.add_argument("--small", type=int, default=64)
    s.add_argument("--big", type=int, default=1024)
    s.add_argument("--spp", type=int, default=16)
    s.add_argument("--big-spp", type=int, default=16)
    s.add_argument("--seeds", type=int, default=4)
    c = commands.add_parser("convergence", help="RMSE against a long reference")
    c.add_argument("gems", nargs="+")
    c.add_argument("--sizes", type=int, nargs="+", default=[64, 128])
    c.add_argument("--spp", type=int, default=16)
    c.add_argument("--reference-spp", type=int, default=4096)
    c.add_argument("--seeds", type=int, default=8,
                   help="render seeds of the test image (its error is heavy-tailed)")
    t = commands.add_parser("turntable", help="the stone's brightness over a turn")
    t.add_argument("gems", nargs="+")
    t.add_argument("--frames", type=int, default=36)
    t.add_argument("--size", type=int, default=128)
    t.add_argument("--spp", type=int, default=16)
    t.add_argument("--seeds", type=int, default=1,
                   help="render seeds; with 2 or more, the share of the change that is noise")
    k = commands.add_parser("look", help="converged footprints against flakes one by one")
    k.add_argument("gems", nargs="+")
    k.add_argument("--sizes", type=int, nargs="+", default=[64, 128])
    k.add_argument("--spp", type=int, default=1024)
    k.add_argument("--picture", help="write the side-by-side PNG here")
    b = commands.add_parser("lobe", help="footprints' mean against flakes one by one")
    b.add_argument("gems", nargs="+")
    b.add_argument("--size", type=int, default=16)
    b.add_argument("--spp", type=int, default=1024)
    b.add_argument("--seeds", type=int, default=8)
    args = parser.parse_args(argv)
    if getattr(args, "seeds", 1) < 1:
        parser.error(f"--seeds must be at least 1, got {args.seeds}")
    args.extra = extra
    with tempfile.TemporaryDirectory() as folder:
        {"scale": scale, "convergence": convergence, "turntable": turntable,
         "lobe": lobe, "look": look}[args.command](args, folder)


if __name__ == "__main__":
    sys.exit(main())
