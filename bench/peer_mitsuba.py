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
  peer_mitsuba.py side-by-side A.exr B.exr OUT.png --gain 4 --zoom 3
  peer_mitsuba.py render OUT.exr --suite-scene env-softbox --env MAP.exr …
  peer_mitsuba.py suite-maps bench/out/suite
  peer_mitsuba.py marker-position IN.exr
"""

import argparse
import math
import re
import sys
from pathlib import Path

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


def ellipsoid_cap_mesh(rings=96, segments=192, semi_axes=STONE_SEMI_AXES):
    """Triangulate the upper half (z >= 0) of an ellipsoid, by default the
    peer stone's.

    Returns (positions (N,3), normals (N,3), faces (F,3) uint32) as numpy
    arrays. Normals are the analytic ellipsoid normals ∇(x²/a² + y²/b² +
    z²/c²) ∝ (x/a², y/b², z/c²), so the smooth coat's highlight does not
    depend on the tessellation. The pole is a single vertex; the open rim
    lies on the ground plane z = 0, where the ground hides it.
    """
    import numpy as np

    a, b, c = semi_axes
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


def turn_about_z(turn_deg):
    """The 3 × 3 rotation by `turn_deg` about z (lapidary's `rotation_deg:
    (0, 0, turn)`), for rows of points: `points @ turn.T`."""
    import numpy as np

    c, s = math.cos(math.radians(turn_deg)), math.sin(math.radians(turn_deg))
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def mesh_of(mi, dr, pos, nrm, faces, props, name="stone"):
    """A Mitsuba mesh named `name` from numpy positions, vertex normals and
    faces, with `props` (its BSDF, and its interior medium if any)."""
    mesh = mi.Mesh(name, len(pos), len(faces), props, has_vertex_normals=True)
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
    props["bsdf"] = mi.load_dict(peer_stone_bsdf(nonlinear))
    return mesh_of(mi, dr, pos, nrm, faces, props)


def clear_stone_mesh(mi, dr, scattering=False, semi_axes=STONE_SEMI_AXES, lift=CLEAR_LIFT,
                     ior=CLEAR_IOR, absorption=CLEAR_ABSORPTION, turn_deg=0.0, xy=(0.0, 0.0),
                     name="stone"):
    """The cap closed by its flat base (z = 0), lifted by `lift`, as a
    smooth `dielectric` of `ior` around a `homogeneous` medium of σa
    `absorption` (per unit), purely absorbing unless `scattering`: True
    for the peer's SCATTERING and SCATTERING_G, or a pair (σs per unit,
    the Henyey-Greenstein g). Turned by `turn_deg` about z and moved by
    `xy` (lapidary's `rotation_deg: (0, 0, turn)` and `position`), the
    mesh named `name`.

    The base is a separate fan of vertices with the normal −z, so the rim
    stays a sharp edge as lapidary's analytic stone has it.
    """
    import numpy as np

    segments = 192
    pos, nrm, faces = ellipsoid_cap_mesh(segments=segments, semi_axes=semi_axes)
    rim = pos[-segments:].copy()  # the last ring: z ≈ c·cos(π/2) = 0
    rim[:, 2] = 0.0
    centre = len(pos)
    base_pos = np.vstack([[0.0, 0.0, 0.0], rim])
    base_nrm = np.tile([0.0, 0.0, -1.0], (len(base_pos), 1))
    cur = np.arange(segments)
    nxt = (cur + 1) % segments
    base_faces = np.stack([np.full(segments, centre), centre + 1 + nxt, centre + 1 + cur], axis=1)
    turn = turn_about_z(turn_deg)
    pos = np.vstack([pos, base_pos]) @ turn.T + np.array([xy[0], xy[1], lift])
    nrm = np.vstack([nrm, base_nrm]) @ turn.T
    faces = np.concatenate([faces, base_faces]).astype(np.uint32)
    props = mi.Properties()
    props["bsdf"] = mi.load_dict({"type": "dielectric", "int_ior": ior, "ext_ior": 1.0})
    if scattering is True:
        scattering = (SCATTERING, SCATTERING_G)
    sigma_s, g = scattering or ((0.0, 0.0, 0.0), 0.0)
    sigma_t = [a + s for a, s in zip(absorption, sigma_s)]
    # Mitsuba reads an RGB σt as a reflectance (each channel ≤ 1): the
    # values are scaled into [0, 1] and `scale` restores them.
    scale = max(sigma_t)
    props["interior"] = mi.load_dict(
        {
            "type": "homogeneous",
            "scale": scale,
            "sigma_t": {"type": "rgb", "value": [t / scale for t in sigma_t]},
            "albedo": {"type": "rgb", "value": [s / t for s, t in zip(sigma_s, sigma_t)]},
            "phase": {"type": "hg", "g": g},
        }
    )
    return mesh_of(mi, dr, pos, nrm, faces, props, name=name)


def scene_dict(mi, dr, size, spp, max_depth, nonlinear=True, clear=False, scattering=False,
               light_radius=LIGHT_RADIUS, environment=True):
    """The whole peer scene as a Mitsuba `load_dict` dictionary.

    `max_depth` follows Mitsuba's `path` convention: 1 = emitters seen
    directly, 2 = direct lighting, so lapidary's `--bounces B` is B + 2.
    A `light_radius` other than LIGHT_RADIUS keeps the light's power (its
    radiance scales by (LIGHT_RADIUS / light_radius)²); `environment` False
    leaves the constant environment out.
    """
    t = mi.ScalarTransform4f
    radiance = LIGHT_RADIANCE * (LIGHT_RADIUS / light_radius) ** 2
    scene = {
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
            "radius": light_radius,
            "emitter": {"type": "area", "radiance": {"type": "rgb", "value": radiance}},
        },
        "environment": {
            "type": "constant",
            "radiance": {"type": "rgb", "value": ENVIRONMENT_RADIANCE},
        },
    }
    if not environment:
        del scene["environment"]
    return scene


def tray_stones_of(path):
    """The stones of a tray scene written by bench/scaling (bench/out/
    tray-N.ron): the common cap's semi-axes and each stone's (x, y) and
    turn about z in degrees."""
    text = Path(path).read_text()
    shape = re.search(r"length: ([-\d.]+), width: ([-\d.]+), dome_height: ([-\d.]+)", text)
    if not shape:
        raise ValueError(f"{path}: no Cabochon(length, width, dome_height) found")
    length, width, dome = map(float, shape.groups())
    placements = [(float(x), float(y), float(turn)) for x, y, turn in re.findall(
        r"position: \(([-\d.]+), ([-\d.]+), 0\.0\),\s*rotation_deg: \(0\.0, 0\.0, ([-\d.]+)\)",
        text)]
    if not placements:
        raise ValueError(f"{path}: no stone positions found")
    return (length / 2, width / 2, dome), placements


#: The tray's caps in Mitsuba: rings and segments of each cap's mesh (992
#: triangles; a stone is about 10 px across at 512²): its image agrees
#: with 48 × 96's within 0.1 %.
TRAY_CAP_RINGS, TRAY_CAP_SEGMENTS = 16, 32


def tray_scene_dict(mi, dr, size, spp, max_depth, tray_path):
    """The peer scene with its stone replaced by the tray of `tray_path`,
    every cap placed into one merged mesh with the peer stone's BSDF.
    (Mitsuba 3's `instance`s of one `shapegroup` render the same image,
    but 25–40× slower in `llvm_ad_rgb`: a user would merge.)"""
    import numpy as np

    scene = scene_dict(mi, dr, size, spp, max_depth)
    semi_axes, placements = tray_stones_of(tray_path)
    pos, nrm, faces = ellipsoid_cap_mesh(TRAY_CAP_RINGS, TRAY_CAP_SEGMENTS, semi_axes)
    all_pos, all_nrm, all_faces = [], [], []
    for k, (x, y, turn) in enumerate(placements):
        turned = turn_about_z(turn)
        all_pos.append(pos @ turned.T + np.array([x, y, 0.0]))
        all_nrm.append(nrm @ turned.T)
        all_faces.append(faces + k * len(pos))
    props = mi.Properties()
    props["bsdf"] = mi.load_dict(peer_stone_bsdf())
    scene["stone"] = mesh_of(mi, dr, np.vstack(all_pos), np.vstack(all_nrm),
                             np.vstack(all_faces).astype(np.uint32), props)
    return scene


# --- The benchmark suite's scenes (bench/suite/, issue 28) -------------------
#
# Built in code like the peer scene; each constant mirrors the RON file named
# beside it and must stay in step with it. Lengths in mm, z up.

#: bench/suite/env-softbox.ron: the orbit camera (target, distance,
#: elevation, azimuth, vertical field of view).
SOFTBOX_CAMERA = ((0.0, 0.0, 1.5), 60.0, 30.0, -70.0, 28.0)
#: Its three stones: ellipsoid cap semi-axes (length/2, width/2, dome),
#: position and turn about z in degrees; all of bench/peer-stone.ron.
SOFTBOX_STONES = (
    ((5.0, 4.0, 4.0), (-3.0, 2.0, 0.0), 20.0),
    ((3.0, 2.4, 2.6), (6.0, -3.0, 0.0), -30.0),
    ((2.0, 1.6, 2.0), (-1.0, -6.0, 0.0), 75.0),
)
#: The soft box: centre, the point it faces, width (horizontal), height, radiance.
SOFTBOX_RECT = ((-25.0, -30.0, 35.0), (0.0, 0.0, 0.0), 24.0, 16.0, 25.0)
#: bench/suite/env-lights.ron's lights besides env-softbox's: rectangles
#: (centre, aim, width, height, radiance) and spheres (centre, radius, radiance).
ENV_LIGHTS_EXTRA_RECTS = (
    ((30.0, -20.0, 30.0), (0.0, 0.0, 0.0), 20.0, 12.0, (12.0, 12.0, 14.0)),
    ((0.0, 35.0, 25.0), (0.0, 0.0, 0.0), 30.0, 10.0, (8.0, 8.0, 8.0)),
)
ENV_LIGHTS_EXTRA_SPHERES = (
    ((-4.0, -14.0, 21.0), 1.5, (300.0, 300.0, 300.0)),
    ((15.0, 10.0, 18.0), 1.0, (200.0, 180.0, 160.0)),
    ((-18.0, 12.0, 12.0), 2.0, (60.0, 60.0, 80.0)),
)
#: bench/suite/glossy-ground.ron: a rough IOR 1.5 coat (10° average slope)
#: over a Lambertian base.
GLOSSY_GROUND_RGB = (0.35, 0.32, 0.3)
GLOSSY_GROUND_IOR = 1.5
GLOSSY_GROUND_SLOPE_DEG = 10.0


def beckmann_alpha_of_blinn(slope_deg):
    """Mitsuba's Beckmann α for lapidary's Blinn lobe of average slope m:
    β = −ln 2 / ln cos m (src/brdf/microfacet.rs), then Walter et al. 2007's
    equivalence α = √(2 / (β + 2)). Both lobes fall to half their peak
    near θh = m (α = tan m, lapidary's own Beckmann convention, falls to
    half at 8.3° for m = 10°: a narrower lobe, which put the sun's glossy
    reflection on sun-map's ground 15–22 % off)."""
    beta = -math.log(2.0) / math.log(math.cos(math.radians(slope_deg)))
    return math.sqrt(2.0 / (beta + 2.0))

#: Side of the suite's square ground in Mitsuba (lapidary's is infinite);
#: the frames see less than 250 mm of it.
SUITE_GROUND_SIDE = 400.0
#: bench/suite/goldstone-*.ron: the studio's camera and key light, a
#: 10 × 8 × 4 mm cap lifted 0.5 mm, a constant environment; the stone of
#: goldstone-clear-stone.ron: IOR 1.53, σa per mm.
GOLDSTONE_CAMERA = ((0.0, 0.0, 1.5), 38.0, 35.0, -60.0, 22.0)
GOLDSTONE_SEMI_AXES = (5.0, 4.0, 4.0)
GOLDSTONE_LIFT = 0.5
GOLDSTONE_IOR = 1.53
GOLDSTONE_ABSORPTION = (0.05, 0.15, 0.3)
GOLDSTONE_LIGHT = ((-4.0, -14.0, 21.0), 1.5, 300.0)
GOLDSTONE_ENVIRONMENT = 0.5
#: bench/suite/orientation.ron: camera at the origin looking along +y, 20°
#: up, 70° vertical field of view; the marker map's markers: name, RGB
#: radiance, azimuth and elevation in degrees, angular radius in degrees.
ORIENTATION_LOOK_AT = (0.0, 1.0, math.tan(math.radians(20.0)))
ORIENTATION_FOV_DEG = 70.0
MARKERS = (
    ("red", (20.0, 0.0, 0.0), 75.0, 30.0, 4.0),
    ("green", (0.0, 20.0, 0.0), 110.0, 5.0, 4.0),
)
#: The generated maps (file name, width): a smooth sky for env-softbox, a
#: dim sky with a small bright sun for sun-map, the markers.
SKY_MAP = ("sky-2048x1024.exr", 2048)
SUN_MAP = ("sun-4096x2048.exr", 4096)
MARKER_MAP = ("marker-512x256.exr", 512)
#: The sun of SUN_MAP: elevation, azimuth, angular radius (degrees), radiance.
SUN = (40.0, 120.0, 0.5, 1.0e5)
#: SUN_MAP's sky is SKY_MAP's sky scaled by this.
SUN_SKY_SCALE = 0.1


def orbit_origin(target, distance, elevation_deg, azimuth_deg):
    """Lapidary's orbit camera: target + d·(cos e cos a, cos e sin a, sin e)."""
    e, a = math.radians(elevation_deg), math.radians(azimuth_deg)
    return [t + distance * c for t, c in
            zip(target, (math.cos(e) * math.cos(a), math.cos(e) * math.sin(a), math.sin(e)))]


def sensor_dict(mi, origin, target, fov_deg, size, spp):
    """A perspective camera with a square box-filtered film, as the peer scene's."""
    return {
        "type": "perspective",
        "fov": fov_deg,
        "fov_axis": "y",
        "to_world": mi.ScalarTransform4f().look_at(origin=list(origin), target=list(target),
                                                   up=[0, 0, 1]),
        "sampler": {"type": "stratified", "sample_count": spp},
        "film": {"type": "hdrfilm", "width": size, "height": size, "pixel_format": "rgb",
                 "rfilter": {"type": "box"}},
    }


def envmap_dict(mi, path):
    """An `envmap` emitter laid out as lapidary's `File` environment.

    Lapidary (src/render/environment.rs, `direction_to_uv`): column u =
    atan2(ω_y, ω_x) / 2π, counter-clockwise from +x seen from above; row
    v = acos(ω_z) / π, row 0 straight up. Mitsuba 3's `envmap` reads the
    local direction d as u = atan2(d_x, −d_z) / 2π, v = acos(d_y) / π (y
    up). Equal (u, v) needs d = (ω_y, ω_z, −ω_x), so to_world maps d back
    to ω: rows (0, 0, −1), (1, 0, 0), (0, 1, 0). That matrix is a
    reflection (determinant −1): the two layouts run round the horizon in
    opposite senses. It is orthogonal, so solid angles and Mitsuba's
    sampling densities are unchanged. `bench/suite/run --check-orientation`
    checks it with markers.
    """
    to_world = mi.ScalarTransform4f(
        [[0.0, 0.0, -1.0, 0.0], [1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0]]
    )
    return {"type": "envmap", "filename": str(path), "to_world": to_world}


def placed_cap(mi, dr, name, semi_axes, position, turn_deg, bsdf):
    """An ellipsoid cap mesh turned by `turn_deg` about z and moved to
    `position` (lapidary's `rotation_deg: (0, 0, turn)` and `position`)."""
    import numpy as np

    pos, nrm, faces = ellipsoid_cap_mesh(semi_axes=semi_axes)
    turn = turn_about_z(turn_deg)
    pos = pos @ turn.T + np.array(position)
    nrm = nrm @ turn.T
    props = mi.Properties()
    props["bsdf"] = mi.load_dict(bsdf)
    return mesh_of(mi, dr, pos, nrm, faces, props, name=name)


def peer_stone_bsdf(nonlinear=True):
    """bench/peer-stone.ron as Mitsuba's `plastic` (`nonlinear`: see
    stone_mesh)."""
    return {"type": "plastic",
            "diffuse_reflectance": {"type": "rgb", "value": list(STONE_BASE_RGB)},
            "int_ior": STONE_COAT_IOR, "ext_ior": 1.0, "nonlinear": nonlinear}


def suite_ground(mi, bsdf):
    """The suite's square ground on z = 0 (lapidary's is infinite)."""
    return {"type": "rectangle",
            "to_world": mi.ScalarTransform4f().scale(
                [SUITE_GROUND_SIDE / 2, SUITE_GROUND_SIDE / 2, 1.0]),
            "bsdf": bsdf}


def suite_scene_dict(mi, dr, name, size, spp, max_depth, env_path=None):
    """One of the suite's scenes (`env-softbox`, `env-lights`, `sun-map`,
    `goldstone-clear`, `orientation`) as a Mitsuba `load_dict` dictionary;
    `env_path` is the generated map of env-softbox, env-lights, sun-map and
    orientation. `sun-map` is env-softbox without its soft box, lit by the
    map alone."""
    scene = {"type": "scene",
             "integrator": {"type": "volpath" if name == "goldstone-clear" else "path",
                            "max_depth": max_depth}}
    if name in ("env-softbox", "env-lights", "sun-map"):
        target, distance, elevation, azimuth, fov = SOFTBOX_CAMERA
        scene["sensor"] = sensor_dict(mi, orbit_origin(target, distance, elevation, azimuth),
                                      target, fov, size, spp)
        for k, (axes, position, turn) in enumerate(SOFTBOX_STONES):
            scene[f"stone{k}"] = placed_cap(mi, dr, f"stone{k}", axes, position, turn,
                                            peer_stone_bsdf())
        scene["ground"] = suite_ground(mi, {
            "type": "roughplastic",
            "distribution": "beckmann",
            "alpha": beckmann_alpha_of_blinn(GLOSSY_GROUND_SLOPE_DEG),
            "int_ior": GLOSSY_GROUND_IOR,
            "ext_ior": 1.0,
            "diffuse_reflectance": {"type": "rgb", "value": list(GLOSSY_GROUND_RGB)},
            "nonlinear": True,
        })
        # Each rectangle is [-1, 1]² with normal +z, emitting on that side;
        # look_at turns +z to the aim and keeps +x horizontal (width).
        rects = [] if name == "sun-map" else [SOFTBOX_RECT]
        if name == "env-lights":
            rects += list(ENV_LIGHTS_EXTRA_RECTS)
            for k, (centre, radius, rgb) in enumerate(ENV_LIGHTS_EXTRA_SPHERES):
                scene[f"sphere{k}"] = {"type": "sphere", "center": list(centre), "radius": radius,
                                       "emitter": {"type": "area",
                                                   "radiance": {"type": "rgb", "value": list(rgb)}}}
        for k, (centre, aim, width, height, radiance) in enumerate(rects):
            rgb = [radiance] * 3 if isinstance(radiance, float) else list(radiance)
            scene["softbox" if k == 0 else f"softbox{k}"] = {
                "type": "rectangle",
                "to_world": mi.ScalarTransform4f().look_at(origin=list(centre), target=list(aim),
                                                           up=[0, 0, 1])
                @ mi.ScalarTransform4f().scale([width / 2, height / 2, 1.0]),
                "emitter": {"type": "area", "radiance": {"type": "rgb", "value": rgb}},
            }
        scene["environment"] = envmap_dict(mi, env_path)
    elif name == "goldstone-clear":
        target, distance, elevation, azimuth, fov = GOLDSTONE_CAMERA
        scene["sensor"] = sensor_dict(mi, orbit_origin(target, distance, elevation, azimuth),
                                      target, fov, size, spp)
        scene["stone"] = clear_stone_mesh(mi, dr, semi_axes=GOLDSTONE_SEMI_AXES,
                                          lift=GOLDSTONE_LIFT, ior=GOLDSTONE_IOR,
                                          absorption=GOLDSTONE_ABSORPTION)
        scene["ground"] = suite_ground(
            mi, {"type": "diffuse", "reflectance": {"type": "rgb", "value": GROUND_ALBEDO}})
        centre, radius, radiance = GOLDSTONE_LIGHT
        scene["light"] = {"type": "sphere", "center": list(centre), "radius": radius,
                          "emitter": {"type": "area",
                                      "radiance": {"type": "rgb", "value": radiance}}}
        scene["environment"] = {"type": "constant",
                                "radiance": {"type": "rgb", "value": GOLDSTONE_ENVIRONMENT}}
    elif name == "orientation":
        scene["sensor"] = sensor_dict(mi, (0.0, 0.0, 0.0), ORIENTATION_LOOK_AT,
                                      ORIENTATION_FOV_DEG, size, spp)
        scene["environment"] = envmap_dict(mi, env_path)
    else:
        raise ValueError(f"unknown suite scene {name!r}")
    return scene


def lat_long_directions(width):
    """Unit directions (H, W, 3) of the texel centres of a width × width/2
    map in lapidary's layout (column u from +x counter-clockwise, row 0 up)."""
    import numpy as np

    height = width // 2
    phi = (np.arange(width) + 0.5) / width * 2.0 * math.pi
    theta = (np.arange(height) + 0.5) / height * math.pi
    st, ct = np.sin(theta)[:, None], np.cos(theta)[:, None]
    return np.stack([st * np.cos(phi), st * np.sin(phi), np.broadcast_to(ct, (height, width))],
                    axis=-1)


def unit(azimuth_deg, elevation_deg):
    """The unit direction of an azimuth (from +x, counter-clockwise) and elevation."""
    a, e = math.radians(azimuth_deg), math.radians(elevation_deg)
    return (math.cos(e) * math.cos(a), math.cos(e) * math.sin(a), math.sin(e))


def sky_texels(width):
    """A smooth sky over a ground, float32 (H, W, 3): warm near the horizon,
    blue towards the zenith, up to twice as bright towards azimuth 200°; a
    dark brown ground below the horizon. No edges, so no texel dominates."""
    import numpy as np

    d = lat_long_directions(width)
    up = np.clip(d[..., 2:3], 0.0, 1.0)
    horizon, zenith = np.array([1.0, 0.95, 0.85]), np.array([0.25, 0.45, 0.9])
    t = np.sqrt(up)
    sky = (1.0 - t) * horizon + t * zenith
    towards = d @ np.array(unit(200.0, 0.0))
    sky *= 1.0 + np.clip(towards, 0.0, 1.0)[..., None] ** 2
    down = np.clip(-d[..., 2:3], 0.0, 1.0)
    ground = np.array([0.12, 0.1, 0.08]) * (1.0 - 0.5 * down)
    return np.where(d[..., 2:3] >= 0.0, sky, ground).astype(np.float32)


def sun_texels(width):
    """SUN_SKY_SCALE × the smooth sky, plus the SUN disc (texels whose
    centre lies within its angular radius)."""
    import numpy as np

    elevation, azimuth, radius_deg, radiance = SUN
    texels = sky_texels(width) * SUN_SKY_SCALE
    inside = lat_long_directions(width) @ np.array(unit(azimuth, elevation)) \
        >= math.cos(math.radians(radius_deg))
    texels[inside] = radiance
    return texels


def marker_texels(width):
    """A black map with the MARKERS' discs."""
    import numpy as np

    d = lat_long_directions(width)
    texels = np.zeros(d.shape, dtype=np.float32)
    for _, rgb, azimuth, elevation, radius_deg in MARKERS:
        inside = d @ np.array(unit(azimuth, elevation)) >= math.cos(math.radians(radius_deg))
        texels[inside] = rgb
    return texels


def suite_maps(args):
    """Write the suite's maps into `args.dir` (those not there yet) as
    float32 EXR through Mitsuba's Bitmap writer; print their paths.
    Deterministic: the same texels on every machine."""
    from pathlib import Path

    import mitsuba as mi

    mi.set_variant("scalar_rgb")
    out = Path(args.dir)
    out.mkdir(parents=True, exist_ok=True)
    for (filename, width), texels in ((SKY_MAP, sky_texels), (SUN_MAP, sun_texels),
                                      (MARKER_MAP, marker_texels)):
        path = out / filename
        if not path.exists():
            tmp = path.with_suffix(".tmp.exr")
            mi.Bitmap(texels(width), mi.Bitmap.PixelFormat.RGB).write(str(tmp))
            tmp.replace(path)
        print(path)


def marker_position(args):
    """Print, per marker colour, the mean pixel (x, y) of the pixels where
    that channel dominates (x right, y down, pixel centres at +0.5), and
    where a pinhole camera of the orientation scene puts the marker's
    centre: the check that a map lands alike in lapidary and Mitsuba."""
    import numpy as np

    rgb = read_rgb(args.src)
    height, width = rgb.shape[:2]
    ys, xs = np.mgrid[0:height, 0:width] + 0.5
    forward = np.array(ORIENTATION_LOOK_AT) / np.linalg.norm(ORIENTATION_LOOK_AT)
    right = np.cross(forward, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    half = math.tan(math.radians(ORIENTATION_FOV_DEG) / 2)
    for channel, (name, _, azimuth, elevation, _) in enumerate(MARKERS):
        c = rgb[..., channel]
        others = np.delete(rgb, channel, axis=-1).max(axis=-1)
        mask = (c > 1.0) & (c > 4.0 * others)
        if mask.any():
            seen = f"{xs[mask].mean():.2f} {ys[mask].mean():.2f} ({mask.sum()} px)"
        else:
            seen = "not seen"
        d = np.array(unit(azimuth, elevation))
        x_ndc = d @ right / (d @ forward) / half
        y_ndc = d @ up / (d @ forward) / half
        expected = f"{(x_ndc + 1) / 2 * width:.2f} {(1 - y_ndc) / 2 * height:.2f}"
        print(f"{name}: at {seen}; a pinhole puts it at {expected}")


def render(args):
    """Build the scene, render it with `llvm_ad_rgb` and write a linear EXR."""
    import drjit as dr
    import mitsuba as mi

    mi.set_variant("llvm_ad_rgb")
    dr.set_thread_count(args.threads)
    if args.tray:
        scene = tray_scene_dict(mi, dr, args.size, args.spp, args.max_depth, args.tray)
    elif args.suite_scene:
        scene = suite_scene_dict(mi, dr, args.suite_scene, args.size, args.spp, args.max_depth,
                                 args.env)
    else:
        scene = scene_dict(
            mi, dr, args.size, args.spp, args.max_depth, not args.linear, args.clear,
            args.scattering, args.light_radius, not args.no_environment,
        )
        if args.no_ground:
            del scene["ground"]
    # The film's filter: a box, or lapidary's own tent of radius one pixel
    # (src/render/film.rs), whose expected image is lapidary's.
    scene["sensor"]["film"]["rfilter"] = {"type": args.filter}
    image = mi.render(mi.load_dict(scene), spp=args.spp, seed=args.seed)
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


def side_by_side(args):
    """Write `a`, `b` and |a − b| × `--gain` side by side as one 8-bit
    sRGB PNG, each enlarged `--zoom` times by repeating pixels (both
    images the same size, linear)."""
    import mitsuba as mi
    import numpy as np

    a, b = read_rgb(args.a), read_rgb(args.b)
    if a.shape != b.shape:
        raise SystemExit(f"side-by-side: {args.a} is {a.shape[:2]}, {args.b} is {b.shape[:2]}")
    panels = np.concatenate([a, b, np.abs(a - b) * args.gain], axis=1)
    panels = panels.repeat(args.zoom, axis=0).repeat(args.zoom, axis=1)
    out = np.round(srgb_encode(panels) * 255.0).astype(np.uint8)
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
    r.add_argument("--seed", type=int, default=0, help="the sampler's seed (mi.render's)")
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
    r.add_argument("--light-radius", type=float, default=LIGHT_RADIUS,
                   help="the sphere light's radius, its radiance scaled to keep its power")
    r.add_argument("--no-environment", action="store_true",
                   help="leave the constant environment out")
    r.add_argument("--suite-scene",
                   choices=("env-softbox", "env-lights", "sun-map", "goldstone-clear",
                            "orientation"),
                   help="render this scene of bench/suite/ instead of the peer scene")
    r.add_argument("--filter", choices=("box", "tent"), default="box",
                   help="the film's reconstruction filter: box (the default, for timings and "
                        "patch means) or tent, radius 1, lapidary's own (for noise)")
    r.add_argument("--tray", help="the peer scene with the stones of this tray scene of "
                                  "bench/scaling (bench/out/tray-N.ron), as one mesh")
    r.add_argument("--env", help="the generated environment map of --suite-scene env-softbox, "
                                 "env-lights, sun-map or orientation (bench/out/suite/…)")
    p = sub.add_parser("to-png", help="downsample + sRGB-encode an image")
    p.add_argument("src")
    p.add_argument("dst")
    p.add_argument("--size", type=int, default=256)
    m = sub.add_parser("patch-mean", help="mean linear RGB of a pixel rectangle")
    m.add_argument("src")
    for name in ("x0", "y0", "x1", "y1"):
        m.add_argument(name, type=int)
    d = sub.add_parser("side-by-side", help="a, b and |a - b| x gain as one sRGB PNG")
    for name in ("a", "b", "dst"):
        d.add_argument(name)
    d.add_argument("--gain", type=float, default=4.0)
    d.add_argument("--zoom", type=int, default=1)
    g = sub.add_parser("suite-maps", help="write bench/suite's environment maps (EXR) into DIR")
    g.add_argument("dir")
    k = sub.add_parser("marker-position",
                       help="where the orientation check's markers landed in an image")
    k.add_argument("src")
    args = parser.parse_args(argv)
    {"render": render, "to-png": to_png, "patch-mean": patch_mean,
     "side-by-side": side_by_side, "suite-maps": suite_maps,
     "marker-position": marker_position}[args.command](args)


if __name__ == "__main__":
    main(sys.argv[1:])
