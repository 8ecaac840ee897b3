#!/usr/bin/env python3
"""Noise at equal samples: one or two lapidary binaries, each against its own reference.

For every binary: a long reference (--reference-spp, seed 0), then
--seeds renders at --spp with seeds 1, 2, …; the RMSE of linear RGB
against that binary's reference over the ground's pixels (material_id 1),
the stones' (material_id ≥ 2) and all, as the square root of the mean over
seeds of each render's mean squared error; and the median render time.
Two binaries run alternately, and their ratios (B / A) close the table.
Each against its own reference, so that a change of the expected image
(e.g. of a compensation table) does not count as noise. A last line gives
the ratios of trimmed RMSEs, without the largest 0.1 % of each binary's
(render, pixel) squared errors, and of the median pixel's RMSE over the
renders: under a small bright source the plain RMSE is decided by a few
caustic pixels of a few renders. Run with
bench/.venv/bin/python (it reads EXRs with Mitsuba's Bitmap):

    bench/.venv/bin/python bench/noise.py --scene bench/suite/env-softbox.ron \\
        --binary /tmp/old/lapidary --binary target/release/lapidary
"""
import argparse
import os
import statistics
import tempfile

from connections import load, render as render_with
from noise_vs_mitsuba import TRIMMED, trimmed_mean
import numpy as np


def render(binary, args, spp, seed, out):
    """One render with connections on (the default), its wall time."""
    return render_with(args, spp, seed, True, out, binary=binary)


REGIONS = {
    "ground": lambda ids: ids == 1,
    "stones": lambda ids: ids >= 2,
    "all": lambda ids: np.ones(ids.shape, bool),
}


def median_pixel(squares):
    """The median over pixels of each pixel's mean squared error over the
    renders (`squares`: one array of the region's pixels per render)."""
    return np.median(np.mean(squares, axis=0))


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("recipe", nargs="?", help="a built-in gem or a gem recipe")
    parser.add_argument("--scene", help="a scene file (default: the studio)")
    parser.add_argument("--binary", action="append", required=True,
                        help="a lapidary binary (once or twice)")
    parser.add_argument("--size", type=int, default=128)
    parser.add_argument("--spp", type=int, default=64)
    parser.add_argument("--seeds", type=int, default=16)
    parser.add_argument("--reference-spp", type=int, default=4096)
    parser.add_argument("--bounces", type=int, default=4)
    args = parser.parse_args()
    # Both binaries compile their materials' tables the same way, cold.
    os.environ["LAPIDARY_CACHE"] = "off"
    if len(args.binary) > 2:
        parser.error("at most two binaries")
    with tempfile.TemporaryDirectory() as folder:
        references, masks = [], None
        for k, binary in enumerate(args.binary):
            path = os.path.join(folder, f"reference-{k}.exr")
            render(binary, args, args.reference_spp, 0, path)
            rgb, ids = load(path)
            references.append(rgb)
            masks = {name: pick(ids) for name, pick in REGIONS.items()}
        squared = [{name: [] for name in REGIONS} for _ in args.binary]
        seconds = [[] for _ in args.binary]
        means = [[] for _ in args.binary]
        for seed in range(1, args.seeds + 1):
            for k, binary in enumerate(args.binary):
                path = os.path.join(folder, f"render-{k}.exr")
                seconds[k].append(render(binary, args, args.spp, seed, path))
                rgb, _ = load(path)
                error = ((rgb - references[k]) ** 2).mean(axis=-1)
                for name, mask in masks.items():
                    squared[k][name].append(error[mask])
                means[k].append(rgb[masks["all"]].mean())
    print(f"{args.scene or 'studio'} {args.recipe or ''} {args.size}², {args.spp} spp, "
          f"{args.seeds} seeds, references {args.reference_spp} spp")
    print("| binary | " + " | ".join(f"RMSE {name} ({masks[name].sum()} px)" for name in REGIONS)
          + " | median time (s) | image mean / reference mean |")
    print("|---|" + "---:|" * (len(REGIONS) + 2))
    rmse = []
    for k, binary in enumerate(args.binary):
        row = {name: np.sqrt(np.mean([v.mean() for v in values]))
               for name, values in squared[k].items()}
        rmse.append(row)
        bias = np.mean(means[k]) / references[k][masks["all"]].mean()
        print(f"| {binary} | " + " | ".join(f"{row[name]:.5f}" for name in REGIONS)
              + f" | {statistics.median(seconds[k]):.2f} | {bias:.4f} |")
    if len(args.binary) == 2:
        ratios = [rmse[1][name] / rmse[0][name] for name in REGIONS]
        time_ratio = statistics.median(seconds[1]) / statistics.median(seconds[0])
        print("| B / A | " + " | ".join(f"{r:.3f}" for r in ratios) + f" | {time_ratio:.3f} | |")
        # Equal error needs samples in proportion to the error's square.
        print(f"time at equal error (all pixels), B / A: {time_ratio * ratios[-1] ** 2:.3f}")
        trimmed = [np.sqrt(trimmed_mean(np.concatenate(squared[1][name]))
                           / trimmed_mean(np.concatenate(squared[0][name]))) for name in REGIONS]
        print(f"| B / A, trimmed of the largest {TRIMMED:.1%} | "
              + " | ".join(f"{r:.3f}" for r in trimmed) + " | | |")
        median = [np.sqrt(median_pixel(squared[1][name]) / median_pixel(squared[0][name]))
                  for name in REGIONS]
        print("| B / A, the median pixel's RMSE over the seeds | "
              + " | ".join(f"{r:.3f}" for r in median) + " | | |")


if __name__ == "__main__":
    main()
