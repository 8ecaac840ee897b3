#!/usr/bin/env python3
"""Noise at equal samples, lapidary against Mitsuba 3, region by region.

Each renderer against its own long reference (seed 0; their means differ
by their models), then --seeds renders at --spp with seeds 1, 2, … of
each; the RMSE of linear RGB over the ground's pixels, the stones', the
stones' highlights (either reference's luminance above 1, or Mitsuba's
alone with --highlights-from mitsuba, grown by --highlight-grow pixels:
the lights' mirror images, whose edges are a few pixels of very large
variance), the
stones' other pixels and all, as the square root of the mean over seeds
of each render's mean squared error, and the ratio lapidary / Mitsuba
with its standard error (from the spread of the renders' MSEs), and the
ratio of trimmed RMSEs (without the largest 0.1 % of the (render, pixel)
squared errors: the caustics that make the plain one heavy-tailed;
meaningful region by region, as over "all" the largest are mostly one
region's), and the ratio of the median pixel's RMSE over the renders. The
regions are lapidary's `material_id` masks (the two images are aligned).
Mitsuba's film is a box; lapidary's default film is a one-pixel tent
(filter importance sampling: each sample in one pixel, placed by the
tent), which spreads a glint's samples into its neighbours: where small
bright things are seen sharply its RMSE reads 1.2-1.3x higher than with
--lapidary-filter box (bench/results/2026-12-05-box-film.md), elsewhere
1.0-1.1x;
--mitsuba-filter tent gives it lapidary's tent, which Mitsuba splats
into neighbouring pixels, so that they share samples; --lapidary-filter
box gives lapidary Mitsuba's box (`lapidary render --filter box`).
Mitsuba renders through bench/peer_mitsuba.py (`llvm_ad_rgb`, max_depth =
--bounces + 2). Run with bench/.venv/bin/python:

    bench/.venv/bin/python bench/noise_vs_mitsuba.py --scene peer --seeds 16
    bench/.venv/bin/python bench/noise_vs_mitsuba.py --scene env-softbox
    (also env-lights, sun-map, goldstone-clear, tray-1000: the suite's
    cases that Mitsuba renders too)
"""
import argparse
import os
import subprocess
import sys
import tempfile
import time

import mitsuba as mi
import numpy as np

BENCH = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(BENCH)
PYTHON = sys.executable
BINARY = os.environ.get("LAPIDARY_BINARY", os.path.join(ROOT, "target", "dist", "lapidary"))
SKY_MAP = os.path.join(BENCH, "out", "suite", "sky-2048x1024.exr")
SUN_MAP = os.path.join(BENCH, "out", "suite", "sun-4096x2048.exr")
TRAY = os.path.join(BENCH, "out", "tray-1000.ron")

# (lapidary's scene file, peer_mitsuba.py's arguments for the same scene):
# every suite case with a Mitsuba twin (bench/suite/run).
SCENES = {
    "peer": (os.path.join(BENCH, "peer-scene.ron"), []),
    "env-softbox": (os.path.join(BENCH, "suite", "env-softbox.ron"),
                    ["--suite-scene", "env-softbox", "--env", SKY_MAP]),
    "env-lights": (os.path.join(BENCH, "suite", "env-lights.ron"),
                   ["--suite-scene", "env-lights", "--env", SKY_MAP]),
    "sun-map": (os.path.join(BENCH, "suite", "sun-map.ron"),
                ["--suite-scene", "sun-map", "--env", SUN_MAP]),
    "goldstone-clear": (os.path.join(BENCH, "suite", "goldstone-clear.ron"),
                        ["--suite-scene", "goldstone-clear"]),
    "tray-1000": (TRAY, ["--tray", TRAY]),
}
LUMINANCE = np.array([0.2126, 0.7152, 0.0722])
#: The share of the largest (render, pixel) squared errors that the
#: trimmed ratio leaves out: caustics of small bright sources in the
#: stones' coats make the plain RMSE heavy-tailed (a few pixels of one
#: render in several decide it), and the trimmed one shows the rest.
TRIMMED = 0.001


def trimmed_mean(squares):
    """The mean of `squares` without its largest TRIMMED share."""
    kept = len(squares) - int(len(squares) * TRIMMED)
    return np.partition(squares, kept - 1)[:kept].mean()


def load(path):
    """Linear RGB and, where the file has one, the material_id layer."""
    bitmap = mi.Bitmap(path)
    names = [field.name for field in bitmap.struct_()]
    pixels = np.array(bitmap, copy=False)
    ids = pixels[..., names.index("material_id")] if "material_id" in names else None
    return pixels[..., :3].astype(np.float64), ids


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", choices=sorted(SCENES), default="peer")
    parser.add_argument("--size", type=int, default=128)
    parser.add_argument("--spp", type=int, default=16)
    parser.add_argument("--seeds", type=int, default=16)
    parser.add_argument("--reference-spp", type=int, default=4096)
    parser.add_argument("--bounces", type=int, default=4)
    parser.add_argument("--mitsuba-filter", choices=("box", "tent"), default="box",
                        help="Mitsuba's pixel filter: box (the default: each sample in one "
                             "pixel, as lapidary's filter importance sampling) or tent "
                             "(lapidary's 1-pixel tent, which Mitsuba splats into "
                             "neighbouring pixels: they share samples)")
    parser.add_argument("--lapidary-filter", choices=("tent", "box", "gaussian"), default="tent",
                        help="lapidary's pixel filter (`render --filter`): its default "
                             "tent, or box, as Mitsuba's default here")
    parser.add_argument("--highlights-from", choices=("either", "mitsuba"), default="either",
                        help="which reference marks the stones' highlights (luminance > 1): "
                             "either one (the default), or Mitsuba's alone, so that the "
                             "regions are the same for every lapidary build compared")
    parser.add_argument("--highlight-grow", type=int, default=0, metavar="PX",
                        help="grow the highlights by PX pixels (4-neighbours), leaving a "
                             "glint's neighbours out of the stones without highlights")
    args = parser.parse_args()
    if args.seeds < 2:
        parser.error("--seeds must be at least 2 (the standard error needs two renders)")
    mi.set_variant("scalar_rgb")
    scene, mitsuba_scene = SCENES[args.scene]
    if not (os.path.exists(SKY_MAP) and os.path.exists(SUN_MAP)):
        subprocess.run([PYTHON, os.path.join(BENCH, "peer_mitsuba.py"), "suite-maps",
                        os.path.dirname(SKY_MAP)], check=True)
    if args.scene == "tray-1000" and not os.path.exists(TRAY):
        sys.exit(f"{TRAY}: missing; `bench/suite/run --only tray-1000` writes it")

    def lapidary(spp, seed, out):
        subprocess.run([BINARY, "render", "-q", "--scene", scene, "--size", str(args.size),
                        "--spp", str(spp), "--seed", str(seed), "--bounces", str(args.bounces),
                        "--filter", args.lapidary_filter, "-o", out], check=True, env=dict(os.environ, LAPIDARY_CACHE="off"))

    def mitsuba(spp, seed, out):
        subprocess.run([PYTHON, os.path.join(BENCH, "peer_mitsuba.py"), "render",
                        "--size", str(args.size), "--spp", str(spp), "--seed", str(seed),
                        "--max-depth", str(args.bounces + 2), "--threads", "2",
                        "--filter", args.mitsuba_filter, *mitsuba_scene, out],
                       check=True, capture_output=True)

    renderers = (("lapidary", lapidary), ("Mitsuba", mitsuba))
    with tempfile.TemporaryDirectory() as folder:
        references = {}
        for name, render in renderers:
            path = os.path.join(folder, f"{name}-reference.exr")
            render(args.reference_spp, 0, path)
            references[name], ids = load(path)
            if name == "lapidary":
                material = ids
        stone = material >= 2
        bright = references["Mitsuba"] @ LUMINANCE
        if args.highlights_from == "either":
            bright = np.maximum(references["lapidary"] @ LUMINANCE, bright)
        highlight = bright > 1.0
        for _ in range(args.highlight_grow):
            grown = highlight.copy()
            grown[1:, :] |= highlight[:-1, :]
            grown[:-1, :] |= highlight[1:, :]
            grown[:, 1:] |= highlight[:, :-1]
            grown[:, :-1] |= highlight[:, 1:]
            highlight = grown
        highlight &= stone
        regions = {
            "ground": material == 1,
            "stones": stone,
            "stones' highlights (reference luminance > 1)": highlight,
            "stones without highlights": stone & ~highlight,
            "all": np.ones(stone.shape, bool),
        }
        # Every (render, pixel) squared error per region, render by render.
        squares = {name: {region: [] for region in regions} for name, _ in renderers}
        times = {name: [] for name, _ in renderers}
        for seed in range(1, args.seeds + 1):
            for name, render in renderers:
                path = os.path.join(folder, f"{name}.exr")
                started = time.perf_counter()
                render(args.spp, seed, path)
                times[name].append(time.perf_counter() - started)
                rgb, _ = load(path)
                for region, mask in regions.items():
                    squares[name][region].append(
                        ((rgb - references[name])[mask] ** 2).mean(axis=-1))
    print(f"{args.scene}, {args.size}², {args.spp} spp, {args.bounces} bounces, "
          f"{args.seeds} seeds, references {args.reference_spp} spp, "
          f"Mitsuba's filter {args.mitsuba_filter}")
    print()
    print("| region | pixels | lapidary RMSE | Mitsuba RMSE | lapidary / Mitsuba | "
          f"trimmed: without the largest {TRIMMED:.1%} | the median pixel's |")
    print("|---|---:|---:|---:|---:|---:|---:|")
    for region, mask in regions.items():
        if not mask.any():
            continue
        # Each render's MSE over the region.
        ours, theirs = (np.array([square.mean() for square in squares[name][region]])
                        for name, _ in renderers)
        ratio = np.sqrt(ours.mean() / theirs.mean())
        # The ratio of root mean MSEs: half the relative standard errors of
        # the two means, added in quadrature.
        spread = np.hypot(ours.std(ddof=1) / ours.mean(), theirs.std(ddof=1) / theirs.mean())
        error = 0.5 * ratio * spread / np.sqrt(args.seeds)
        ours_trimmed, theirs_trimmed = (trimmed_mean(np.concatenate(squares[name][region]))
                                        for name, _ in renderers)
        # Each pixel's MSE over the renders, the median pixel's.
        ours_median, theirs_median = (np.median(np.mean(squares[name][region], axis=0))
                                      for name, _ in renderers)
        print(f"| {region} | {int(mask.sum())} | {np.sqrt(ours.mean()):.4f} | "
              f"{np.sqrt(theirs.mean()):.4f} | {ratio:.3f} ± {error:.3f} | "
              f"{np.sqrt(ours_trimmed / theirs_trimmed):.3f} | "
              f"{np.sqrt(ours_median / theirs_median):.3f} |")
    print()
    print("median whole-process time of one render: "
          + ", ".join(f"{name} {np.median(times[name]):.2f} s" for name, _ in renderers))


if __name__ == "__main__":
    main()
