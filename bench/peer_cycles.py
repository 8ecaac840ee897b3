#!/usr/bin/env python3
"""Render lapidary's peer scene (bench/peer-scene.ron, issue 6) in Blender Cycles.

Runs inside bench/.venv with the `bpy` module (Blender as a Python module,
`bpy==5.0.1`). The scene constants and the ellipsoid cap mesh come from
peer_mitsuba.py so the two peers cannot drift apart.

Usage:
  peer_cycles.py OUT.exr --size 512 --spp 64 --max-bounces 4 --threads 2
"""

import argparse
import math
import os
import sys
import warnings

sys.dont_write_bytecode = True  # keep bench/ free of __pycache__
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import peer_mitsuba as peer  # noqa: E402  (scene constants and the stone mesh)


def sphere_light_watts(radiance, radius):
    """Blender's point-light power for a sphere light of uniform radiance L.

    Radiometry: a Lambertian emitter of radiance L and area A emits
    Φ = π·L·A (exitance M = π L, integrated over the area), and a sphere of
    radius r has A = 4π r², so Φ = 4π² r² L. Cycles' point light with
    `shadow_soft_size` r (soft falloff off) emits radiance Φ / (4π² r²),
    i.e. it uses the radiometric watt; bench/README.md records the ground
    patch check that confirms this numerically against lapidary and Mitsuba.
    """
    return 4.0 * math.pi**2 * radius**2 * radiance


def reset(bpy):
    """Start from an empty file so no default cube, lamp or camera leaks in."""
    bpy.ops.wm.read_factory_settings(use_empty=True)


def configure(bpy, scene, args):
    """Render settings: CPU, fixed threads and spp, no denoise, no adaptivity."""
    scene.render.engine = "CYCLES"
    cyc = scene.cycles
    cyc.device = "CPU"
    cyc.samples = args.spp
    cyc.use_adaptive_sampling = False
    cyc.use_denoising = False
    cyc.seed = 0
    cyc.pixel_filter_type = "BOX"
    cyc.max_bounces = args.max_bounces
    cyc.diffuse_bounces = args.max_bounces
    cyc.glossy_bounces = args.max_bounces
    cyc.transmission_bounces = args.max_bounces
    cyc.volume_bounces = 0
    cyc.sample_clamp_direct = 0.0  # 0 = no clamping (the default clamps indirect at 10)
    cyc.sample_clamp_indirect = 0.0
    cyc.blur_glossy = 0.0
    cyc.caustics_reflective = True
    cyc.caustics_refractive = True
    scene.render.threads_mode = "FIXED"
    scene.render.threads = args.threads
    scene.render.resolution_x = args.size
    scene.render.resolution_y = args.size
    scene.render.resolution_percentage = 100
    scene.render.film_transparent = False
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    scene.view_settings.exposure = 0.0
    scene.view_settings.gamma = 1.0
    settings = scene.render.image_settings
    settings.file_format = "OPEN_EXR"
    settings.color_depth = "32"
    settings.color_mode = "RGB"
    scene.render.use_file_extension = False
    scene.render.filepath = os.path.abspath(args.out)


def add_object(bpy, scene, name, data, location=(0.0, 0.0, 0.0)):
    """Link a new object holding `data` into the scene."""
    obj = bpy.data.objects.new(name, data)
    obj.location = location
    scene.collection.objects.link(obj)
    return obj


def add_camera(bpy, scene):
    """Orbit camera of the issue: 30° vertical FOV, looking at the origin, z up."""
    from mathutils import Vector

    cam = bpy.data.cameras.new("camera")
    cam.sensor_fit = "VERTICAL"
    cam.angle_y = math.radians(peer.CAMERA_VERTICAL_FOV_DEG)
    cam.clip_start, cam.clip_end = 0.01, 1000.0
    origin = Vector(peer.camera_origin())
    obj = add_object(bpy, scene, "camera", cam, origin)
    # Cameras look down their local −z with local +y up.
    obj.rotation_euler = (-origin).to_track_quat("-Z", "Y").to_euler()
    scene.camera = obj


def node_material(bpy, name, shader, inputs):
    """A material whose surface is one shader node with the given input values."""
    mat = bpy.data.materials.new(name)
    with warnings.catch_warnings():  # deprecated in Blender 5 (always on), needed before
        warnings.simplefilter("ignore", DeprecationWarning)
        mat.use_nodes = True
    tree = mat.node_tree
    tree.nodes.clear()
    node = tree.nodes.new(shader)
    for key, value in inputs.items():
        node.inputs[key].default_value = value
    out = tree.nodes.new("ShaderNodeOutputMaterial")
    tree.links.new(node.outputs[0], out.inputs["Surface"])
    return mat


def add_stone(bpy, scene):
    """The ellipsoid cap with a Principled BSDF: smooth IOR 1.5 over green diffuse."""
    pos, nrm, faces = peer.ellipsoid_cap_mesh()
    mesh = bpy.data.meshes.new("stone")
    mesh.from_pydata(pos.tolist(), [], faces.tolist())
    mesh.shade_smooth()
    mesh.normals_split_custom_set_from_vertices(nrm.tolist())
    rgba = (*peer.STONE_BASE_RGB, 1.0)
    mat = node_material(
        bpy,
        "stone",
        "ShaderNodeBsdfPrincipled",
        {"Base Color": rgba, "Roughness": 0.0, "IOR": peer.STONE_COAT_IOR, "Metallic": 0.0},
    )
    mesh.materials.append(mat)
    add_object(bpy, scene, "stone", mesh)


def add_ground(bpy, scene):
    """A 40 × 40 Lambertian square on z = 0, albedo 0.5."""
    h = peer.GROUND_SIDE / 2
    mesh = bpy.data.meshes.new("ground")
    mesh.from_pydata([(-h, -h, 0), (h, -h, 0), (h, h, 0), (-h, h, 0)], [], [(0, 1, 2, 3)])
    g = peer.GROUND_ALBEDO
    mat = node_material(
        bpy, "ground", "ShaderNodeBsdfDiffuse", {"Color": (g, g, g, 1.0), "Roughness": 0.0}
    )
    mesh.materials.append(mat)
    add_object(bpy, scene, "ground", mesh)


def add_light(bpy, scene):
    """The sphere light as a Cycles point light with a radius (soft falloff off)."""
    light = bpy.data.lights.new("light", type="POINT")
    light.energy = sphere_light_watts(peer.LIGHT_RADIANCE, peer.LIGHT_RADIUS)
    light.shadow_soft_size = peer.LIGHT_RADIUS
    if hasattr(light, "use_soft_falloff"):
        light.use_soft_falloff = False  # a true sphere, not Eevee-style falloff
    light.color = (1.0, 1.0, 1.0)
    add_object(bpy, scene, "light", light, peer.LIGHT_CENTRE)


def add_world(bpy, scene):
    """Constant environment of radiance 0.2 (Background strength × white)."""
    world = bpy.data.worlds.new("world")
    with warnings.catch_warnings():  # deprecated in Blender 5 (always on), needed before
        warnings.simplefilter("ignore", DeprecationWarning)
        world.use_nodes = True
    bg = world.node_tree.nodes["Background"]
    bg.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    bg.inputs["Strength"].default_value = peer.ENVIRONMENT_RADIANCE
    scene.world = world


def main(argv):
    """Build the scene, render it and write a linear float EXR."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out")
    parser.add_argument("--size", type=int, default=512)
    parser.add_argument("--spp", type=int, default=64)
    parser.add_argument("--max-bounces", type=int, default=4)
    parser.add_argument("--threads", type=int, default=2)
    args = parser.parse_args(argv)
    import bpy

    reset(bpy)
    scene = bpy.context.scene
    configure(bpy, scene, args)
    add_camera(bpy, scene)
    add_stone(bpy, scene)
    add_ground(bpy, scene)
    add_light(bpy, scene)
    add_world(bpy, scene)
    bpy.ops.render.render(write_still=True)


if __name__ == "__main__":
    main(sys.argv[1:])
