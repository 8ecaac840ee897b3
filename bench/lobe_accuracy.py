#!/usr/bin/env python3
"""How closely each library material's lobe follows its random walk.

For every built-in material (or the ones named) and each incidence angle,
runs `lapidary brdf NAME --slice THETA_I --reference` (f·cosθₒ in the plane
of incidence, θₒ from −87° to 87° in 3° steps, beside the random walk's)
and prints one Markdown table of the green channel:

- *L1 error*: Σ|model − walk| / Σ walk over the slice's angles, each
  weighted by cosθₒ's share of the plane (|sin| steps are not uniform, but
  the slice is what the user sees in `lapidary brdf -o`): 0 when the two
  lobes coincide, 2 when they do not overlap at all;
- *peak ratio*: the model's largest value over the walk's largest;
- *peak shift*: where the model peaks minus where the walk peaks, degrees.

The model is the full BRDF as renders use it (single crossing plus the
compensation lobe) unless `--single-crossing`. Standard library only; the
walk's noise (2 M paths a slice, fixed seed) shows where the walk is
small: read errors of materials whose walk is dark with care.

    bench/lobe_accuracy.py                       # every material, 0°, 30°, 60°
    bench/lobe_accuracy.py silver-paint gold --angles 0,45
"""

import argparse
import math
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def library_materials(lapidary):
    """The built-in material names, from `lapidary list`."""
    out = subprocess.run([lapidary, "list"], capture_output=True, text=True, check=True).stdout
    names, in_materials = [], False
    for line in out.splitlines():
        if line.startswith("Materials"):
            in_materials = True
        elif line.startswith("Gems"):
            break
        elif in_materials and line.strip():
            names.append(line.split()[0])
    return names


def slice_of(lapidary, name, theta_i, single_crossing):
    """[(θₒ, model, walk)] of the green channel."""
    cmd = [lapidary, "brdf", name, "--slice", str(theta_i), "--reference"]
    if single_crossing:
        cmd.append("--single-crossing")
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode != 0:
        sys.exit(f"bench/lobe_accuracy.py: `{' '.join(cmd)}` failed: {proc.stderr.strip()}")
    rows = []
    for line in proc.stdout.splitlines()[1:]:
        v = [float(x) for x in line.split(",")]
        rows.append((v[0], v[2], v[5]))
    return rows


def compare(rows):
    """(L1 error, peak ratio, peak shift in degrees) of one slice."""
    weights = [math.cos(math.radians(t)) for t, _, _ in rows]
    walk_sum = sum(w * r for w, (_, _, r) in zip(weights, rows))
    diff_sum = sum(w * abs(m - r) for w, (_, m, r) in zip(weights, rows))
    model_peak = max(rows, key=lambda row: row[1])
    walk_peak = max(rows, key=lambda row: row[2])
    l1 = diff_sum / walk_sum if walk_sum > 0 else float("nan")
    ratio = model_peak[1] / walk_peak[2] if walk_peak[2] > 0 else float("nan")
    return l1, ratio, model_peak[0] - walk_peak[0]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("materials", nargs="*", help="library names or material files (default: all)")
    ap.add_argument("--angles", default="0,30,60", help="incidence angles, degrees (default 0,30,60)")
    ap.add_argument("--single-crossing", action="store_true",
                    help="the model without its compensation lobe")
    ap.add_argument("--lapidary", default=str(ROOT / "target" / "release" / "lapidary"),
                    help="the binary (default target/release/lapidary)")
    args = ap.parse_args()
    angles = [float(a) for a in args.angles.split(",")]
    names = args.materials or library_materials(args.lapidary)
    model = "single crossing" if args.single_crossing else "single crossing + compensation"
    print(f"Model: {model}; green channel; L1 error / peak ratio / peak shift (°) per incidence.\n")
    print("| material | " + " | ".join(f"θᵢ = {a:g}°" for a in angles) + " |")
    print("|---|" + "---:|" * len(angles))
    for name in names:
        cells = []
        for a in angles:
            l1, ratio, shift = compare(slice_of(args.lapidary, name, a, args.single_crossing))
            cells.append(f"{l1:.2f} / {ratio:.2f} / {shift:+.0f}")
        print(f"| {name} | " + " | ".join(cells) + " |", flush=True)


if __name__ == "__main__":
    main()
