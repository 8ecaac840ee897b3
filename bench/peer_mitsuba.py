#!/usr/bin/env python3
"""Render lapidary's peer scene (bench/peer-scene.ron, issue 6) in Mitsuba 3.

Runs inside bench/.venv (created by `bench/compare --install`). The scene is
built in code, not parsed from the RON file; the constants below are the
issue's scene and must stay in step with bench/peer-scene.ron. This module
also holds what the Cycles peer shares (the scene constants and the ellipsoid
cap mesh) and the image helpers the driver calls (`--to-png`, `--patch-mean`),
so the driver itself needs nothing outside the standard library.

Usage:
  peer_mitsuba.py render OUT.exr --size 512 --spp 64 --max-depth 6 --threads 2
  peer_mitsuba.py to-png IN.exr OUT.png --size 256
  peer_mitsuba.py patch-mean IN.exr X0 Y0 X1 Y1
"""

import argparse
import math
import sys

# --- The scene of issue 6 (scene units, z up) --------------------------------

#: Semi-axes of the ellipsoid whose upper half (z >= 0) is the cabochon.
STONE_SEMI_AXES = (1.0, 0.7, 0.45)
#: Diffuse base albedo under the smooth IOR 1.5 coat.
STONE_BASE_RGB = (0.1, 0.5, 0.2)
#: Index of refraction of the stone's clear coat.
STONE_COAT_IOR = 1.5
#: Side of the square Lambertian ground on z = 0 (lapidary's is infinite).
GROUND_SIDE = 40.0
#: Lambertian albedo of the ground.
GROUND_ALBEDO = 0.5
#: Orbit camera: distance from the origin, elevation above the horizon, on −y.
CAMERA_DISTANCE = 5.0
CAMERA_ELEVATION_DEG = 35.0
CAMERA_VERTICAL_FOV_DEG = 30.0
#: Sphere light: centre, radius and (uniform, white) emitted radiance.
LIGHT_CENTRE = (2.5, -2.0, 4.0)
LIGHT_RADIUS = 0.25
LIGHT_RADIANCE = 500.0
#: Constant environment radiance.
ENVIRONMENT_RADIANCE = 0.2
#: The clear variant (bench/peer-scene-clear.ron): the same cap, closed by
#: its flat base and lifted this far above the ground, a smooth dielectric
#: of this IOR over a purely absorbing medium with this σa per unit.
CLEAR_LIFT = 0.1
CLEAR_IOR = 1.5
CLEAR_ABSORPTION = (0.3, 0.1, 0.6)
#: The scattering variant (bench/peer-scene-scattering.ron): the clear
#: stone's absorption plus this σs per unit, Henyey–Greenstein with this g.
SCATTERING = (0.5, 0.5, 0.5)
SCATTERING_G = 0.5


def camera_origin():
    """Camera position: on the −y side, CAMERA_ELEVATION_DEG above the horizon.

    Lapidary's orbit camera puts the eye at target + d·(cos e cos a,
    cos e sin a, sin e) with azimuth a = −90°, i.e. (0, −d cos e, d sin e).
    """
    e = math.radians(CAMERA_ELEVATION_DEG)
    return (0.0, -CAMERA_DISTANCE * math.cos(e), CAMERA_DISTANCE * math.sin(e))


def ellipsoid_cap_mesh(rings=96, segments=192):
    """Triangulate the upper half (z >= 0) of the stone's ellipsoid.

    Returns (positions (N,3), normals (N,3), faces (F,3) uint32) as numpy
    arrays. Normals are the analytic ellipsoid normals ∇(x²/a² + y²/b² +
    z²/c²) ∝ (x/a², y/b², z/c²), so the smooth coat's highlight does not
    depend on the tessellation. The pole is a single vertex; the open rim
    lies on the ground plane z = 0, where the ground hides it.
    """
    import numpy as np

    a, b, c = STONE_SEMI_AXES
    theta = np.linspace(0.0, 0.5 * math.pi, rings + 1)[1:]  # polar angle from +z
    phi = np.linspace(0.0, 2.0 * math.pi, segments, endpoint=False)
    st, ct = np.sin(theta)[:, None], np.cos(theta)[:, None]
    x = (a * st * np.cos(phi)).ravel()
    y = (b * st * np.sin(phi)).ravel()
    z = np.broadcast_to(c * ct, (rings, segments)).ravel()
    pos = np.vstack([[0.0, 0.0, c], np.stack([x, y, z], axis=1)])
    nrm = pos / np.array([a * a, b * b, c * c])
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    faces = []
    nxt = (np.arange(segments) + 1) % segments
    cur = np.arange(segments)
    faces.append(np.stack([np.zeros(segments, int), 1 + cur, 1 + nxt], axis=1))
    for r in range(rings - 1):
        top, bot = 1 + r * segments, 1 + (r + 1) * segments
        faces.append(np.stack([top + cur, bot + cur, bot + nxt], axis=1))
        faces.append(np.stack([top + cur, bot + nxt, top + nxt], axis=1))
    return pos, nrm, np.concatenate(faces).astype(np.uint32)


# --- Mitsuba ------------------------------------------------------------------


def mesh_of(mi, dr, pos, nrm, faces, props):
    """A Mitsuba mesh named `stone` from numpy positions, vertex normals and
    faces, with `props` (its BSDF, and its interior medium if any)."""
    mesh = mi.Mesh("stone", len(pos), len(faces), props, has_vertex_normals=True)
    params = mi.traverse(mesh)
    params["vertex_positions"] = dr.ravel(mi.Point3f(pos[:, 0], pos[:, 1], pos[:, 2]))
    params["vertex_normals"] = dr.ravel(mi.Normal3f(nrm[:, 0], nrm[:, 1], nrm[:, 2]))
    params["faces"] = dr.ravel(mi.Vector3u(faces[:, 0], faces[:, 1], faces[:, 2]))
    params.update()
    return mesh


def stone_mesh(mi, dr, nonlinear=True):
    """The cabochon as a Mitsuba mesh with the `plastic` BSDF of the issue.

    `nonlinear` true (the default) makes the diffuse reflectance the albedo
    of the base itself, with the physical series ρ / (1 − ρ·F_dr) of light
    reflected back down by the coat: a coat *over* a (0.1, 0.5, 0.2) base,
    as the issue says and as lapidary models it. False treats it as the
    albedo seen through the coat (used only for the check in bench/README.md).
    """
    pos, nrm, faces = ellipsoid_cap_mesh()
    props = mi.Properties()
    props["bsdf"] = mi.load_dict(
        {
            "type": "plastic",
            "diffuse_reflectance": {"type": "rgb", "value": list(STONE_BASE_RGB)},
            "int_ior": STONE_COAT_IOR,
            "ext_ior": 1.0,
            "nonlinear": nonlinear,
        }
    )
    return mesh_of(mi, dr, pos, nrm, faces, props)


def clear_stone_mesh(mi, dr, scattering=False):
    """The cap closed by its flat base (z = 0), lifted by CLEAR_LIFT, as a
    smooth `dielectric` around a `homogeneous`, purely absorbing medium.

    The base is a separate fan of vertices with the normal −z, so the rim
    stays a sharp edge as lapidary's analytic stone has it.
    """
    import numpy as np

    pos, nrm, faces = ellipsoid_cap_mesh()
    rim = pos[-192:].copy()  # the last ring: z ≈ c·cos(π/2) = 0
    rim[:, 2] = 0.0
    centre = len(pos)
    base_pos = np.vstack([[0.0, 0.0, 0.0], rim])
    base_nrm = np.tile([0.0, 0.0, -1.0], (len(base_pos), 1))
    segments = len(rim)
    cur = np.arange(segments)
    nxt = (cur + 1) % segments
    base_faces = np.stack([np.full(segments, centre), centre + 1 + nxt, centre + 1 + cur], axis=1)
    pos = np.vstack([pos, base_pos])
    pos[:, 2] += CLEAR_LIFT
    nrm = np.vstack([nrm, base_nrm])
    faces = np.concatenate([faces, base_faces]).astype(np.uint32)
    props = mi.Properties()
    props["bsdf"] = mi.load_dict({"type": "dielectric", "int_ior": CLEAR_IOR, "ext_ior": 1.0})
    sigma_s = SCATTERING if scattering else (0.0, 0.0, 0.0)
    sigma_t = [a + s for a, s in zip(CLEAR_ABSORPTION, sigma_s)]
    # Mitsuba reads an RGB σt as a reflectance (each channel ≤ 1): the
    # values are scaled into [0, 1] and `scale` restores them.
    scale = max(sigma_t)
    props["interior"] = mi.load_dict(
        {
            "type": "homogeneous",
            "scale": scale,
            "sigma_t": {"type": "rgb", "value": [t / scale for t in sigma_t]},
            "albedo": {"type": "rgb", "value": [s / t for s, t in zip(sigma_s, sigma_t)]},
            "phase": {"type": "hg", "g": SCATTERING_G},
        }
    )
    return mesh_of(mi, dr, pos, nrm, faces, props)


def scene_dict(mi, dr, size, spp, max_depth, nonlinear=True, clear=False, scattering=False):
    """The whole peer scene as a Mitsuba `load_dict` dictionary.

    `max_depth` follows Mitsuba's `path` convention: 1 = emitters seen
    directly, 2 = direct lighting, so lapidary's `--bounces B` is B + 2.
    """
    t = mi.ScalarTransform4f
    return {
        "type": "scene",
        "integrator": {
            "type": "volpath" if clear or scattering else "path",
            "max_depth": max_depth,
        },
        "sensor": {
            "type": "perspective",
            "fov": CAMERA_VERTICAL_FOV_DEG,
            "fov_axis": "y",
            "to_world": t().look_at(origin=camera_origin(), target=[0, 0, 0], up=[0, 0, 1]),
            "sampler": {"type": "stratified", "sample_count": spp},
            "film": {
                "type": "hdrfilm",
                "width": size,
                "height": size,
                "pixel_format": "rgb",
                "rfilter": {"type": "box"},
            },
        },
        "stone": (
            clear_stone_mesh(mi, dr, scattering)
            if clear or scattering
            else stone_mesh(mi, dr, nonlinear)
        ),
        "ground": {
            "type": "rectangle",  # [-1, 1]² in the xy plane, normal +z
            "to_world": t().scale([GROUND_SIDE / 2, GROUND_SIDE / 2, 1.0]),
            "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": GROUND_ALBEDO}},
        },
        "light": {
            "type": "sphere",
            "center": list(LIGHT_CENTRE),
            "radius": LIGHT_RADIUS,
            "emitter": {"type": "area", "radiance": {"type": "rgb", "value": LIGHT_RADIANCE}},
        },
        "environment": {
            "type": "constant",
            "radiance": {"type": "rgb", "value": ENVIRONMENT_RADIANCE},
        },
    }


def render(args):
    """Build the scene, render it with `llvm_ad_rgb` and write a linear EXR."""
    import drjit as dr
    import mitsuba as mi

    mi.set_variant("llvm_ad_rgb")
    dr.set_thread_count(args.threads)
    scene = mi.load_dict(
        scene_dict(
            mi, dr, args.size, args.spp, args.max_depth, not args.linear, args.clear, args.scattering
        )
    )
    if args.no_ground:
        scene = mi.load_dict(
            {k: v for k, v in scene_dict(
                mi, dr, args.size, args.spp, args.max_depth, not args.linear, args.clear,
                args.scattering,
            ).items() if k != "ground"}
        )
    image = mi.render(scene, spp=args.spp, seed=0)
    mi.util.write_bitmap(args.out, image)


# --- Image helpers for the driver -------------------------------------------


def read_rgb(path):
    """Read the RGB channels of an EXR (or any Bitmap format) as float32 (H, W, 3)."""
    import mitsuba as mi
    import numpy as np

    mi.set_variant("scalar_rgb")
    bitmap = mi.Bitmap(path)
    channels = [field.name for field in bitmap.struct_()]
    data = np.array(bitmap, dtype=np.float32, copy=False)
    if data.ndim == 2:
        data = data[:, :, None]
    index = [channels.index(name) for name in ("R", "G", "B")]
    return np.ascontiguousarray(data[:, :, index])


def srgb_encode(linear):
    """The plain sRGB transfer curve (IEC 61966-2-1) after clipping to [0, 1]."""
    import numpy as np

    x = np.clip(linear, 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)


def to_png(args):
    """Box-downsample a linear image to `--size` and write it as 8-bit sRGB PNG.

    Exposure 0, no tone curve beyond the sRGB transfer function: values
    above 1 clip, so the three renderers are shown the same way.
    """
    import mitsuba as mi
    import numpy as np

    rgb = read_rgb(args.src)
    factor = rgb.shape[0] // args.size
    if factor > 1:
        h, w = rgb.shape[0] // factor, rgb.shape[1] // factor
        rgb = rgb[: h * factor, : w * factor].reshape(h, factor, w, factor, 3).mean(axis=(1, 3))
    out = np.round(srgb_encode(rgb) * 255.0).astype(np.uint8)
    mi.Bitmap(out, mi.Bitmap.PixelFormat.RGB).write(args.dst)


def patch_mean(args):
    """Print the mean linear R, G, B over pixels [x0, x1) × [y0, y1)."""
    rgb = read_rgb(args.src)
    patch = rgb[args.y0 : args.y1, args.x0 : args.x1].reshape(-1, 3)
    print(" ".join(f"{v:.6f}" for v in patch.mean(axis=0)))


def main(argv):
    """Parse the sub-command and run it."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    r = sub.add_parser("render", help="render the peer scene to a linear EXR")
    r.add_argument("out")
    r.add_argument("--size", type=int, default=512)
    r.add_argument("--spp", type=int, default=64)
    r.add_argument("--max-depth", type=int, default=6)
    r.add_argument("--threads", type=int, default=2)
    r.add_argument(
        "--linear", action="store_true", help="plastic nonlinear=false (check only)"
    )
    r.add_argument(
        "--clear",
        action="store_true",
        help="the clear absorbing stone of bench/peer-scene-clear.ron (volpath)",
    )
    r.add_argument(
        "--scattering",
        action="store_true",
        help="the scattering stone of bench/peer-scene-scattering.ron (volpath)",
    )
    r.add_argument("--no-ground", action="store_true", help="leave the ground out")
    p = sub.add_parser("to-png", help="downsample + sRGB-encode an image")
    p.add_argument("src")
    p.add_argument("dst")
    p.add_argument("--size", type=int, default=256)
    m = sub.add_parser("patch-mean", help="mean linear RGB of a pixel rectangle")
    m.add_argument("src")
    for name in ("x0", "y0", "x1", "y1"):
        m.add_argument(name, type=int)
    args = parser.parse_args(argv)
    {"render": render, "to-png": to_png, "patch-mean": patch_mean}[args.command](args)


if __name__ == "__main__":
    main(sys.argv[1:])
