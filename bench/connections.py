#!/usr/bin/env python3
"""What manifold next-event estimation gains inside translucent stones.

Renders one gem or scene three ways with the release build of lapidary:
a long reference (connections on), connections on at --spp, and
connections off (LAPIDARY_MNEE=off) at the samples that take the same time,
then prints each one's RMSE against the reference over the stone's pixels
(material_id >= 2). Pixels where the reference exceeds --clip (the light's
own mirror image in the polish, a delta path both sample alike) are left
out. Run with bench/.venv/bin/python (it reads EXRs with Mitsuba's Bitmap):

    bench/.venv/bin/python bench/connections.py goldstone --size 128 --spp 64
    bench/.venv/bin/python bench/connections.py --scene my.ron --bounces 2
"""
import argparse
import os
import subprocess
import sys
import tempfile
import time

import mitsuba as mi
import numpy as np

mi.set_variant("scalar_rgb")
ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BINARY = os.environ.get("LAPIDARY_BINARY", os.path.join(ROOT, "target", "release", "lapidary"))


def render(args, spp, seed, connections, out, binary=BINARY):
    command = [binary, "render", "-q", "--size", str(args.size), "--spp", str(spp),
               "--seed", str(seed), "--bounces", str(args.bounces), "-o", out]
    if args.scene:
        command += ["--scene", args.scene]
    if args.recipe:
        command.append(args.recipe)
    env = dict(os.environ, LAPIDARY_MNEE="on" if connections else "off")
    started = time.perf_counter()
    subprocess.run(command, env=env, check=True)
    return time.perf_counter() - started


def load(path):
    bitmap = mi.Bitmap(path)
    names = [field.name for field in bitmap.struct_()]
    pixels = np.array(bitmap, copy=False)
    return pixels[..., :3].astype(np.float64), pixels[..., names.index("material_id")]


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("recipe", nargs="?", help="a built-in gem or a gem recipe")
    parser.add_argument("--scene", help="a scene file (default: the studio)")
    parser.add_argument("--size", type=int, default=128)
    parser.add_argument("--spp", type=int, default=64)
    parser.add_argument("--reference-spp", type=int, default=2048)
    parser.add_argument("--bounces", type=int, default=4)
    parser.add_argument("--clip", type=float, default=1.0)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as folder:
        path = lambda name: os.path.join(folder, name + ".exr")
        render(args, args.reference_spp, 1, True, path("reference"))
        t_on = render(args, args.spp, 2, True, path("on"))
        t_off = render(args, args.spp, 2, False, path("off"))
        equal_spp = max(1, round(args.spp * t_on / t_off))
        t_equal = render(args, equal_spp, 2, False, path("off-equal"))
        reference, material = load(path("reference"))
        mask = (material >= 2) & (reference.max(-1) <= args.clip)
        print(f"{mask.sum()} stone pixels; reference {args.reference_spp} spp; "
              f"connections cost {t_on / t_off:.2f}x per sample")
        rows = [("connections", args.spp, t_on, "on"), ("sampling alone", args.spp, t_off, "off"),
                ("sampling alone, equal time", equal_spp, t_equal, "off-equal")]
        errors = {}
        for label, spp, seconds, name in rows:
            image, _ = load(path(name))
            errors[name] = np.sqrt(((image[mask] - reference[mask]) ** 2).mean())
            print(f"| {label} | {spp} spp | {seconds:.2f} s | RMSE {errors[name]:.5f} |")
        print(f"equal-time RMSE ratio (sampling alone / connections): "
              f"{errors['off-equal'] / errors['on']:.2f}")


if __name__ == "__main__":
    sys.exit(main())
