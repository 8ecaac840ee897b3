#!/usr/bin/env python3
"""bench/random_vs_mitsuba.py: lapidary against Mitsuba 3 on scenes no one tuned for.

Issue 28 asks for speed on the suite *and on other scenes of the same
kinds*. This draws such scenes at random, of the kinds Mitsuba can render
alike: one to four coated stones (ellipsoid caps of bench/peer-stone.ron,
Mitsuba's `plastic`) of random sizes, places and turns; a glossy layered
ground (bench/suite/glossy-ground.ron, `roughplastic`) or a Lambert one
(bench/peer-ground.ron, `diffuse`); zero to four sphere and rectangle
lights; a constant sky, the smooth 2048 × 1024 sky map or the 4096 × 2048
map with a sun; a random orbit camera. With `--translucent` every stone
is instead a translucent body, as suite case 5 without its flakes: a
smooth dielectric of random IOR around a random absorbing medium, clear
or scattering (Henyey-Greenstein), lifted 0.5 mm off the ground
(Mitsuba's `dielectric` around a `homogeneous` medium, `volpath`). Each scene is written as a RON file
for lapidary and built in code for Mitsuba (bench/peer_mitsuba.py's
helpers), and both render it as whole processes, alternately, `--rounds`
times: the table gives the median times, their ratio, and the ratio of
the two images' means per channel (box films in both), which says whether
the two renderers agree on the scene (the stones' and the glossy ground's
models differ by a few per cent, see bench/peer_mitsuba.py; a scene whose
camera is behind a soft box is marked, since lapidary's soft box lets rays
through from behind and Mitsuba's rectangle does not). With
`--noise`, also each renderer's RMSE at 128², 16 spp over `--seeds`
renders against its own `--reference-spp` render (box films in both), the
ratio plain and trimmed of the largest 0.1 % of squared errors, and the
time to equal error, ratio² × the time ratio.

    bench/.venv/bin/python bench/random_vs_mitsuba.py --scenes 8 --rounds 2
    bench/.venv/bin/python bench/random_vs_mitsuba.py --scenes 8 --record   # also bench/results/DATE-random-vs-mitsuba.md
    bench/.venv/bin/python bench/random_vs_mitsuba.py --scenes 8 --noise    # and noise at equal spp, time to equal error
    bench/.venv/bin/python bench/random_vs_mitsuba.py --scenes 8 --translucent   # glass stones instead

Needs bench/.venv (`bench/compare --install`), the suite's maps
(`bench/.venv/bin/python bench/peer_mitsuba.py suite-maps bench/out/suite`)
and target/dist/lapidary (`cargo build --profile dist`). The scene files
stay in bench/out/random/ for a second look.
"""

import argparse
import datetime
import functools
import importlib.machinery
import importlib.util
import json
import math
import platform
import random
import statistics
import subprocess
import sys
from pathlib import Path

# Importing bench/peer_mitsuba.py must not leave a __pycache__ in bench/.
sys.dont_write_bytecode = True

BENCH = Path(__file__).resolve().parent
ROOT = BENCH.parent
OUT = BENCH / "out" / "random"
MAPS = BENCH / "out" / "suite"
LAPIDARY = ROOT / "target" / "dist" / "lapidary"
#: Half the side of Mitsuba's square ground (lapidary's is infinite).
GROUND_HALF_SIDE_MM = 1.0e5


@functools.cache
def load_script(name, path):
    """Import a bench script (bench/compare has no .py suffix), once."""
    loader = importlib.machinery.SourceFileLoader(name, str(path))
    module = importlib.util.module_from_spec(importlib.util.spec_from_loader(name, loader))
    loader.exec_module(module)
    return module


# --- The scenes ---------------------------------------------------------------


def draw_scene(seed):
    """A random scene's parameters (lengths in mm, z up), a pure function of `seed`."""
    rng = random.Random(seed)
    stones = []
    for _ in range(rng.choice([1, 1, 2, 3, 4])):
        a = rng.uniform(2.0, 5.5)
        axes = (a, a * rng.uniform(0.6, 1.0), a * rng.uniform(0.5, 1.0))
        # Apart from the others by their largest half-lengths plus 1 mm.
        for _ in range(100):
            position = (rng.uniform(-12.0, 12.0), rng.uniform(-12.0, 12.0))
            if all(math.dist(position, other["position"][:2]) > a + other["axes"][0] + 1.0
                   for other in stones):
                break
        else:
            continue
        stones.append({"axes": axes, "position": (*position, 0.0), "turn": rng.uniform(0, 180)})
    lights = []
    for _ in range(rng.choice([0, 1, 1, 2, 4])):
        azimuth, elevation = rng.uniform(0, 360), rng.uniform(15, 70)
        distance = rng.uniform(25, 50)
        e, az = math.radians(elevation), math.radians(azimuth)
        centre = (distance * math.cos(e) * math.cos(az), distance * math.cos(e) * math.sin(az),
                  distance * math.sin(e))
        if rng.random() < 0.5:
            radius = rng.uniform(0.5, 3.0)
            # About 1 to 4 of irradiance at the stones: L·π(r/d)².
            radiance = rng.uniform(1.0, 4.0) * (distance / radius) ** 2 / math.pi
            lights.append({"kind": "sphere", "centre": centre, "radius": radius,
                           "radiance": radiance})
        else:
            width, height = rng.uniform(5, 30), rng.uniform(5, 20)
            radiance = rng.uniform(1.0, 4.0) * distance ** 2 / (width * height)
            lights.append({"kind": "rect", "centre": centre, "width": width, "height": height,
                           "radiance": radiance})
    environment = rng.choice(["constant", "sky", "sun"])
    return {
        "seed": seed,
        "camera": ((0.0, 0.0, 1.5), rng.uniform(45, 90), rng.uniform(15, 60),
                   rng.uniform(-180, 180), rng.uniform(22, 35)),
        "stones": stones,
        "ground": rng.choice(["glossy", "lambert"]),
        "lights": lights,
        "environment": environment,
        "constant": rng.uniform(0.2, 1.0),
        "map_turn_deg": rng.uniform(0, 360),
    }


#: How high a translucent stone's flat base sits above the ground, mm (as
#: the suite's goldstone: light passes under it).
TRANSLUCENT_LIFT_MM = 0.5


def make_translucent(scene):
    """Turn every stone of `scene` into a translucent body, drawn from its
    own stream (the same scene's other draws stay those of `draw_scene`):
    IOR 1.45–1.8, σa 0.02–0.4 per mm a channel, and for half of them a grey
    σs 0.2–1.5 per mm with g 0–0.7."""
    rng = random.Random(f"translucent-{scene['seed']}")
    for stone in scene["stones"]:
        stone["ior"] = rng.uniform(1.45, 1.8)
        stone["absorption"] = [rng.uniform(0.02, 0.4) for _ in range(3)]
        if rng.random() < 0.5:
            sigma_s = rng.uniform(0.2, 1.5)
            stone["scattering"] = ((sigma_s,) * 3, rng.uniform(0.0, 0.7))
    return scene


def stone_recipe(scene, k):
    """The path of the recipe of stone `k` of `scene`: bench/peer-stone.ron,
    or for a translucent stone a recipe written now into bench/out/random/."""
    stone = scene["stones"][k]
    if "ior" not in stone:
        return BENCH / "peer-stone.ron"
    path = OUT / f"stone-{scene['seed']}-{k}.ron"
    body = f"ior: {stone['ior']!r}, absorption: {tuple(stone['absorption'])!r}"
    if "scattering" in stone:
        sigma_s, g = stone["scattering"]
        body += f", scattering: {tuple(sigma_s)!r}, anisotropy: {g!r}"
    path.write_text(f'Gem(name: "random {scene["seed"]}-{k}", surface: "teflon", '
                    f"body: Translucent({body}))\n")
    return path


def map_path(scene):
    """The environment map file of a map scene (made by peer_mitsuba.py suite-maps)."""
    return MAPS / ("sky-2048x1024.exr" if scene["environment"] == "sky" else "sun-4096x2048.exr")


def camera_behind_a_rect(scene):
    """Whether the camera is behind a soft box's plane. The twins then may
    differ: lapidary's soft box is one-sided and lets rays through from
    behind, Mitsuba's rectangle is an opaque card there (black: its
    default BSDF is one-sided), and hides what lies behind it."""
    target, distance, elevation, azimuth, _ = scene["camera"]
    e, a = math.radians(elevation), math.radians(azimuth)
    camera = [t + distance * c for t, c in
              zip(target, (math.cos(e) * math.cos(a), math.cos(e) * math.sin(a), math.sin(e)))]
    # A soft box faces the origin: its normal is −centre.
    return any(sum((camera[i] - light["centre"][i]) * -light["centre"][i] for i in range(3)) < 0
               for light in scene["lights"] if light["kind"] == "rect")


def describe(scene):
    """A short description for the table."""
    lights = [light["kind"] for light in scene["lights"]]
    kinds = ["scattering" if "scattering" in s else "clear" if "ior" in s else "coated"
             for s in scene["stones"]]
    stones = ", ".join(f"{kinds.count(k)} {k}" for k in ("coated", "clear", "scattering")
                       if k in kinds)
    counts = ", ".join(f"{lights.count(k)} {k}" for k in ("sphere", "rect") if k in lights)
    behind = " (camera behind a soft box)" if camera_behind_a_rect(scene) else ""
    return (f"{len(scene['stones'])} stone(s) ({stones}), {scene['ground']} ground, "
            f"{counts or 'no lights'}, {scene['environment']} sky{behind}")


def stone_position(stone):
    """Where the stone's flat base sits: on the ground, or a translucent one
    TRANSLUCENT_LIFT_MM above it."""
    x, y, z = stone["position"]
    return (x, y, z + (TRANSLUCENT_LIFT_MM if "ior" in stone else 0.0))


def lapidary_ron(scene):
    """The scene as lapidary's RON."""
    target, distance, elevation, azimuth, fov = scene["camera"]
    stones = [
        f'Stone(recipe: Some("{stone_recipe(scene, k)}"), shape: Cabochon(outline: Oval, '
        f"length: {2 * s['axes'][0]!r}, width: {2 * s['axes'][1]!r}, dome_height: {s['axes'][2]!r}, "
        f"profile_exponent: 2.0, girdle_height: 0.0, base: Flat), "
        f"position: {stone_position(s)!r}, rotation_deg: (0.0, 0.0, {s['turn']!r}))"
        for k, s in enumerate(scene["stones"])
    ]
    ground = (BENCH / "suite" / "glossy-ground.ron" if scene["ground"] == "glossy"
              else BENCH / "peer-ground.ron")
    lights = []
    for light in scene["lights"]:
        c, r = tuple(light["centre"]), (light["radiance"],) * 3
        if light["kind"] == "sphere":
            lights.append(f"Sphere(centre: {c!r}, radius: {light['radius']!r}, radiance: {r!r})")
        else:
            lights.append(f"Rect(centre: {c!r}, aim_at: (0.0, 0.0, 0.0), width: {light['width']!r}, "
                          f"height: {light['height']!r}, radiance: {r!r})")
    if scene["environment"] == "constant":
        environment = f"Constant(radiance: {(scene['constant'],) * 3!r})"
    else:
        environment = (f'File(path: "{map_path(scene)}", rotation_deg: {scene["map_turn_deg"]!r})')
    return (f"Scene(camera: Orbit(target: {tuple(target)!r}, distance: {distance!r}, "
            f"elevation_deg: {elevation!r}, azimuth_deg: {azimuth!r}, vertical_fov_deg: {fov!r}), "
            f"stones: [{', '.join(stones)}], ground: Some(Ground(height: 0.0, material: \"{ground}\")), "
            f"lights: [{', '.join(lights)}], environment: {environment})\n")


def mitsuba_scene(mi, dr, peer, scene, size, spp, max_depth):
    """The scene as a Mitsuba `load_dict` dictionary (peer_mitsuba.py's helpers)."""
    target, distance, elevation, azimuth, fov = scene["camera"]
    translucent = any("ior" in stone for stone in scene["stones"])
    result = {"type": "scene",
              "integrator": {"type": "volpath" if translucent else "path", "max_depth": max_depth},
              "sensor": peer.sensor_dict(mi, peer.orbit_origin(target, distance, elevation, azimuth),
                                         target, fov, size, spp)}
    for k, stone in enumerate(scene["stones"]):
        if "ior" in stone:
            result[f"stone{k}"] = peer.clear_stone_mesh(
                mi, dr, stone.get("scattering", False), semi_axes=stone["axes"],
                lift=stone_position(stone)[2], ior=stone["ior"], absorption=stone["absorption"],
                turn_deg=stone["turn"], xy=stone["position"][:2], name=f"stone{k}")
            continue
        result[f"stone{k}"] = peer.placed_cap(mi, dr, f"stone{k}", stone["axes"],
                                              stone["position"], stone["turn"],
                                              peer.peer_stone_bsdf())
    if scene["ground"] == "glossy":
        bsdf = {"type": "roughplastic", "distribution": "beckmann",
                "alpha": peer.beckmann_alpha_of_blinn(peer.GLOSSY_GROUND_SLOPE_DEG),
                "int_ior": peer.GLOSSY_GROUND_IOR, "ext_ior": 1.0,
                "diffuse_reflectance": {"type": "rgb", "value": list(peer.GLOSSY_GROUND_RGB)},
                "nonlinear": True}
    else:
        bsdf = {"type": "diffuse", "reflectance": {"type": "rgb", "value": peer.GROUND_ALBEDO}}
    # lapidary's ground is infinite: a square wide enough that even a low
    # camera's top rows meet it (the suite's 400 mm one is not).
    result["ground"] = {"type": "rectangle", "bsdf": bsdf,
                        "to_world": mi.ScalarTransform4f().scale([GROUND_HALF_SIDE_MM] * 2 + [1.0])}
    for k, light in enumerate(scene["lights"]):
        emitter = {"type": "area", "radiance": {"type": "rgb", "value": [light["radiance"]] * 3}}
        if light["kind"] == "sphere":
            result[f"light{k}"] = {"type": "sphere", "center": list(light["centre"]),
                                   "radius": light["radius"], "emitter": emitter}
        else:
            # [-1, 1]² with normal +z, turned to face the origin, +x horizontal.
            result[f"light{k}"] = {
                "type": "rectangle",
                "to_world": mi.ScalarTransform4f().look_at(origin=list(light["centre"]),
                                                           target=[0, 0, 0], up=[0, 0, 1])
                @ mi.ScalarTransform4f().scale([light["width"] / 2, light["height"] / 2, 1.0]),
                "emitter": emitter}
    if scene["environment"] == "constant":
        result["environment"] = {"type": "constant",
                                 "radiance": {"type": "rgb", "value": scene["constant"]}}
    else:
        env = peer.envmap_dict(mi, map_path(scene))
        # lapidary's rotation_deg turns the map about world z.
        env["to_world"] = mi.ScalarTransform4f().rotate([0, 0, 1], scene["map_turn_deg"]) @ env["to_world"]
        result["environment"] = env
    return result


def render_mitsuba(args):
    """Child mode: render one scene's JSON with Mitsuba into an EXR."""
    import drjit as dr
    import mitsuba as mi

    peer = load_script("peer_mitsuba", BENCH / "peer_mitsuba.py")
    mi.set_variant("llvm_ad_rgb")
    dr.set_thread_count(args.threads)
    scene = json.loads(Path(args.scene).read_text())
    built = mitsuba_scene(mi, dr, peer, scene, args.size, args.spp, args.max_depth)
    image = mi.render(mi.load_dict(built), spp=args.spp, seed=args.seed)
    mi.util.write_bitmap(args.out, image)


# --- The run --------------------------------------------------------------------


def mean_rgb(path):
    """The mean of an EXR's R, G and B."""
    import numpy as np

    peer = load_script("peer_mitsuba", BENCH / "peer_mitsuba.py")
    return np.asarray(peer.read_rgb(str(path)), dtype=np.float64).reshape(-1, 3).mean(axis=0)


def noise(args, scene, commands):
    """RMSE of each renderer at 128², 16 spp against its own long render:
    (lapidary / Mitsuba plain, the same trimmed of its largest squared
    errors as bench/noise_vs_mitsuba.py trims them: a sun's caustics make
    the plain one heavy-tailed)."""
    import numpy as np
    from noise_vs_mitsuba import trimmed_mean

    peer = load_script("peer_mitsuba", BENCH / "peer_mitsuba.py")
    seed = scene["seed"]
    squares = {}
    for who in ("lapidary", "mitsuba"):
        def render(spp, render_seed, out):
            cmd = list(commands[seed][who])
            for option, value in (("--size", 128), ("--spp", spp)):
                cmd[cmd.index(option) + 1] = str(value)
            cmd[cmd.index(str(OUT / f"{who}-{seed}.exr"))] = str(out)
            subprocess.run([*cmd, "--seed", str(render_seed)], check=True, capture_output=True,
                           env=load_script("bench_compare", BENCH / "compare").peer_env())
            return np.asarray(peer.read_rgb(str(out)), dtype=np.float64)
        reference = render(args.reference_spp, 0, OUT / f"noise-{who}-reference.exr")
        squares[who] = np.concatenate([
            ((render(16, k, OUT / f"noise-{who}.exr") - reference) ** 2).ravel()
            for k in range(1, args.seeds + 1)])

    plain = math.sqrt(squares["lapidary"].mean() / squares["mitsuba"].mean())
    return plain, math.sqrt(trimmed_mean(squares["lapidary"]) / trimmed_mean(squares["mitsuba"]))


def run(args):
    compare = load_script("bench_compare", BENCH / "compare")
    if not LAPIDARY.exists():
        sys.exit(f"{LAPIDARY} is missing: cargo build --profile dist")
    for name in ("sky-2048x1024.exr", "sun-4096x2048.exr"):
        if not (MAPS / name).exists():
            sys.exit(f"{MAPS / name} is missing: bench/.venv/bin/python bench/peer_mitsuba.py "
                     f"suite-maps {MAPS}")
    OUT.mkdir(parents=True, exist_ok=True)
    scenes = [draw_scene(args.first_seed + k) for k in range(args.scenes)]
    if args.translucent:
        scenes = [make_translucent(scene) for scene in scenes]
    commands = {}
    for scene in scenes:
        seed = scene["seed"]
        ron, params = OUT / f"scene-{seed}.ron", OUT / f"scene-{seed}.json"
        ron.write_text(lapidary_ron(scene))
        params.write_text(json.dumps(scene))
        commands[seed] = {
            "lapidary": [str(LAPIDARY), "render", "--scene", str(ron), "-o",
                         str(OUT / f"lapidary-{seed}.exr"), "--size", str(args.size), "--spp",
                         str(args.spp), "--bounces", str(args.bounces), "--filter", "box",
                         "--threads", str(args.threads), "-q"],
            "mitsuba": [sys.executable, __file__, "mitsuba", str(params),
                        str(OUT / f"mitsuba-{seed}.exr"), "--size", str(args.size), "--spp",
                        str(args.spp), "--max-depth", str(args.bounces + 2), "--threads",
                        str(args.threads)],
        }
    times = {seed: {"lapidary": [], "mitsuba": []} for seed in commands}
    for round_index in range(args.rounds):
        for seed, pair in commands.items():
            order = ["lapidary", "mitsuba"] if round_index % 2 == 0 else ["mitsuba", "lapidary"]
            for who in order:
                seconds, _ = compare.timed_run(f"{who} scene {seed}", pair[who],
                                               OUT / f"{who}-{seed}.log")
                times[seed][who].append(seconds)
                print(f"  round {round_index + 1}/{args.rounds}  scene {seed:<3} {who:<9}"
                      f" {seconds:7.2f} s", file=sys.stderr, flush=True)
    head = "| scene | what | lapidary s | Mitsuba s | lapidary / Mitsuba | mean lapidary / Mitsuba (R, G, B) |"
    rule = "|---:|---|---:|---:|---:|---|"
    if args.noise:
        head += " noise at equal spp (trimmed) | time to equal error (trimmed) |"
        rule += "---:|---:|"
    lines = [head, rule]
    ratios = []
    # Scenes whose twins agree (no camera behind a soft box): their time
    # ratios and, with --noise, their trimmed times to equal error.
    like_ratios, like_equal_error = [], []
    for scene in scenes:
        seed = scene["seed"]
        lap, mts = (statistics.median(times[seed][w]) for w in ("lapidary", "mitsuba"))
        ratio = statistics.median(a / b for a, b in zip(times[seed]["lapidary"],
                                                        times[seed]["mitsuba"]))
        ratios.append(ratio)
        like = not camera_behind_a_rect(scene)
        if like:
            like_ratios.append(ratio)
        means = mean_rgb(OUT / f"lapidary-{seed}.exr") / mean_rgb(OUT / f"mitsuba-{seed}.exr")
        line = (f"| {seed} | {describe(scene)} | {lap:.2f} | {mts:.2f} | {ratio:.3f} | "
                + ", ".join(f"{m:.3f}" for m in means) + " |")
        if args.noise:
            plain, trim = noise(args, scene, commands)
            if like:
                like_equal_error.append(trim ** 2 * ratio)
            line += (f" {plain:.3f} ({trim:.3f}) | {plain ** 2 * ratio:.3f} "
                     f"({trim ** 2 * ratio:.3f}) |")
            print(f"  noise scene {seed}: {plain:.3f} ({trim:.3f})", file=sys.stderr, flush=True)
        lines.append(line)
    summary = (f"Ratio of times over the {len(ratios)} scenes: median {statistics.median(ratios):.3f}, "
               f"range {min(ratios):.3f}–{max(ratios):.3f}.")
    if like_ratios and len(like_ratios) < len(ratios):
        summary += (f" Like for like ({len(like_ratios)} scenes, no camera behind a soft box): "
                    f"median {statistics.median(like_ratios):.3f}, "
                    f"range {min(like_ratios):.3f}–{max(like_ratios):.3f}.")
    if like_equal_error:
        within = sum(1 for x in like_equal_error if x <= 0.5)
        summary += (f" Time to equal error (trimmed) over the {len(like_equal_error)} like-for-like "
                    f"scenes: median {statistics.median(like_equal_error):.3f}, "
                    f"range {min(like_equal_error):.3f}–{max(like_equal_error):.3f}, "
                    f"≤ 0.5 on {within}.")
    table = "\n".join(lines)
    print(table)
    print()
    print(summary)
    if args.record:
        commit = subprocess.run(["git", "rev-parse", "HEAD"], cwd=ROOT, capture_output=True,
                                text=True).stdout.strip()
        date = datetime.date.today().isoformat()
        path = BENCH / "results" / f"{date}-random-vs-mitsuba.md"
        run_index = 1
        while path.exists():  # a later run that day: -2, -3, …
            run_index += 1
            path = BENCH / "results" / f"{date}-random-vs-mitsuba-{run_index}.md"
        path.write_text(
            f"# {date} — lapidary against Mitsuba 3 on random scenes (issue 28)\n\n"
            f"- commit: {commit}\n- host: {platform.processor() or platform.machine()}, "
            f"{platform.system()}\n"
            f"- command: `bench/.venv/bin/python bench/random_vs_mitsuba.py --scenes {args.scenes} "
            f"--rounds {args.rounds} --first-seed {args.first_seed}"
            f"{' --translucent' if args.translucent else ''}"
            f"{' --noise --seeds ' + str(args.seeds) + ' --reference-spp ' + str(args.reference_spp) if args.noise else ''}"
            f"` ({args.size}², {args.spp} spp, "
            f"{args.bounces} bounces, {args.threads} threads, box films, whole processes, "
            f"medians of the rounds)\n\n{table}\n\n{summary}\n")
        print(f"written to {path.relative_to(ROOT)}")


def main(argv):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = p.add_subparsers(dest="command")
    m = sub.add_parser("mitsuba", help="(child) render one scene's JSON with Mitsuba")
    m.add_argument("scene")
    m.add_argument("out")
    m.add_argument("--size", type=int, required=True)
    m.add_argument("--spp", type=int, required=True)
    m.add_argument("--max-depth", type=int, required=True)
    m.add_argument("--threads", type=int, default=2)
    m.add_argument("--seed", type=int, default=0)
    for option, default in (("--scenes", 8), ("--rounds", 2), ("--first-seed", 1), ("--size", 512),
                            ("--spp", 64), ("--bounces", 4), ("--threads", 2)):
        p.add_argument(option, type=int, default=default)
    p.add_argument("--noise", action="store_true",
                   help="also noise at equal spp: RMSE at 128², 16 spp over --seeds renders, "
                        "each renderer against its own --reference-spp render")
    p.add_argument("--translucent", action="store_true",
                   help="every stone a translucent body (clear or scattering glass)")
    p.add_argument("--seeds", type=int, default=8)
    p.add_argument("--reference-spp", type=int, default=2048)
    p.add_argument("--record", action="store_true",
                   help="also write bench/results/YYYY-MM-DD-random-vs-mitsuba.md (-2, … for later runs)")
    args = p.parse_args(argv)
    if args.command == "mitsuba":
        render_mitsuba(args)
    else:
        run(args)


if __name__ == "__main__":
    main(sys.argv[1:])
