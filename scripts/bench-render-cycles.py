"""Renders a scene saved by `matseg bench-render --write-scene DIR` with
Blender Cycles (the `bpy` wheel from PyPI) at the same size, samples and
bounces, and prints the timings as one JSON line.

The scene is rebuilt from DIR/scene.json and the world-space meshes
DIR/object_K.obj: each material becomes a Principled BSDF (PBR maps through
a Mapping node for the placement, or constants), each split of a surface
layout a Mix Shader whose factor is the photo channel through the ramp;
the HDRI lights the world. Usage (scripts/bench-render-cycles.sh sets up the
venv and runs both): python bench-render-cycles.py DIR [THREADS]
"""

import json
import os
import resource
import sys
import time

import bpy
from mathutils import Vector

MAP_FILES = {
    "color": ("Color", "basecolor", "OriginColor"),
    "roughness": ("Roughness",),
    "metalness": ("Metalness", "Metallic"),
    "normal": ("NormalGL", "Normal"),
}


def find_map(folder, names):
    for f in sorted(os.listdir(folder)):
        stem = os.path.splitext(f)[0]
        if stem in names or stem.split("_")[-1] in names:
            return os.path.join(folder, f)
    return None


def mapping(nodes, links, placement):
    uv = nodes.new("ShaderNodeTexCoord")
    m = nodes.new("ShaderNodeMapping")
    s = 1.0 / placement["scale"]
    m.inputs["Location"].default_value = (placement.get("offset", [0, 0])[0], placement.get("offset", [0, 0])[1], 0)
    m.inputs["Rotation"].default_value = (0, 0, placement.get("rotation_deg", 0.0) * 3.14159265 / 180)
    m.inputs["Scale"].default_value = (s, s, 1)
    links.new(uv.outputs["UV"], m.inputs["Vector"])
    return m.outputs["Vector"]


def image_node(nodes, links, path, vector, colour):
    t = nodes.new("ShaderNodeTexImage")
    t.image = bpy.data.images.load(path, check_existing=True)
    t.image.colorspace_settings.name = "sRGB" if colour else "Non-Color"
    links.new(vector, t.inputs["Vector"])
    return t


def material_shader(nodes, links, d, base):
    bsdf = nodes.new("ShaderNodeBsdfPrincipled")
    c = d.get("base_color", {"x": 0.5, "y": 0.5, "z": 0.5})
    bsdf.inputs["Base Color"].default_value = (c["x"], c["y"], c["z"], 1)
    bsdf.inputs["Roughness"].default_value = d.get("roughness", 0.5)
    bsdf.inputs["Metallic"].default_value = d.get("metallic", 0.0)
    bsdf.inputs["Transmission Weight"].default_value = d.get("transmission", 0.0)
    bsdf.inputs["IOR"].default_value = d.get("ior", 1.45)
    if d.get("pbr"):
        folder = d["pbr"] if os.path.isabs(d["pbr"]) else os.path.join(base, d["pbr"])
        vector = mapping(nodes, links, d.get("placement", {"scale": 1.0}))
        for role, names in MAP_FILES.items():
            path = find_map(folder, names)
            if path is None:
                continue
            t = image_node(nodes, links, path, vector, role == "color")
            if role == "color":
                links.new(t.outputs["Color"], bsdf.inputs["Base Color"])
            elif role == "roughness":
                links.new(t.outputs["Color"], bsdf.inputs["Roughness"])
            elif role == "metalness":
                links.new(t.outputs["Color"], bsdf.inputs["Metallic"])
            else:
                nm = nodes.new("ShaderNodeNormalMap")
                links.new(t.outputs["Color"], nm.inputs["Color"])
                links.new(nm.outputs["Normal"], bsdf.inputs["Normal"])
    return bsdf.outputs["BSDF"]


def channel_factor(nodes, links, scene, split, base):
    m = scene["maps"][split["map"]]
    photo = m["photo"] if os.path.isabs(m["photo"]) else os.path.join(base, m["photo"])
    t = image_node(nodes, links, photo, mapping(nodes, links, split["placement"]), False)
    sep = nodes.new("ShaderNodeSeparateColor")
    channel = m["channel"]
    sep.mode = "RGB" if channel in "RGB" else "HSV"
    links.new(t.outputs["Color"], sep.inputs["Color"])
    out = sep.outputs[{"R": 0, "G": 1, "B": 2, "H": 0, "S": 1, "V": 2}[channel]]
    ramp = split["ramp"]
    r = nodes.new("ShaderNodeMapRange")
    r.clamp = True
    r.inputs["From Min"].default_value = ramp["low"]
    r.inputs["From Max"].default_value = max(ramp["high"], ramp["low"] + 1e-4)
    links.new(out, r.inputs["Value"])
    return r.outputs["Result"]


def layout_shader(nodes, links, scene, layout, base):
    if "material" in layout:
        return material_shader(nodes, links, scene["materials"][layout["material"]], base)
    split = layout["split"]
    mix = nodes.new("ShaderNodeMixShader")
    links.new(channel_factor(nodes, links, scene, split, base), mix.inputs["Fac"])
    links.new(layout_shader(nodes, links, scene, split["below"], base), mix.inputs[1])
    links.new(layout_shader(nodes, links, scene, split["above"], base), mix.inputs[2])
    return mix.outputs["Shader"]


def main():
    scene_dir = sys.argv[1]
    threads = int(sys.argv[2]) if len(sys.argv) > 2 else os.cpu_count()
    start = time.time()
    with open(os.path.join(scene_dir, "scene.json")) as f:
        scene = json.load(f)
    bpy.ops.wm.read_factory_settings(use_empty=True)
    s = bpy.context.scene
    for k, obj_desc in enumerate(scene["objects"]):
        bpy.ops.wm.obj_import(filepath=os.path.join(scene_dir, f"object_{k}.obj"), forward_axis="Y", up_axis="Z")
        obj = bpy.context.selected_objects[0]
        mat = bpy.data.materials.new(f"m{k}")
        mat.use_nodes = True
        nodes, links = mat.node_tree.nodes, mat.node_tree.links
        nodes.clear()
        out = nodes.new("ShaderNodeOutputMaterial")
        links.new(layout_shader(nodes, links, scene, obj_desc["surface"], scene_dir), out.inputs["Surface"])
        obj.data.materials.clear()
        obj.data.materials.append(mat)
    env = scene["environment"]
    world = bpy.data.worlds.new("world")
    s.world = world
    world.use_nodes = True
    wn, wl = world.node_tree.nodes, world.node_tree.links
    wn.clear()
    tex = wn.new("ShaderNodeTexEnvironment")
    tex.image = bpy.data.images.load(env["hdri"])
    coords = wn.new("ShaderNodeTexCoord")
    rot = wn.new("ShaderNodeMapping")
    rot.inputs["Rotation"].default_value = (0, 0, env.get("rotation_deg", 0) * 3.14159265 / 180)
    wl.new(coords.outputs["Generated"], rot.inputs["Vector"])
    wl.new(rot.outputs["Vector"], tex.inputs["Vector"])
    bg = wn.new("ShaderNodeBackground")
    bg.inputs["Strength"].default_value = env.get("strength", 1.0)
    wl.new(tex.outputs["Color"], bg.inputs["Color"])
    wout = wn.new("ShaderNodeOutputWorld")
    wl.new(bg.outputs["Background"], wout.inputs["Surface"])
    cam_desc = scene["camera"]
    cam_data = bpy.data.cameras.new("camera")
    cam_data.lens = cam_desc.get("focal_mm", 50.0)
    cam_data.sensor_width = 36.0
    cam_data.sensor_fit = "AUTO"
    cam = bpy.data.objects.new("camera", cam_data)
    s.collection.objects.link(cam)
    p, t = cam_desc["position"], cam_desc["target"]
    cam.location = (p["x"], p["y"], p["z"])
    direction = Vector((t["x"], t["y"], t["z"])) - cam.location
    cam.rotation_euler = direction.to_track_quat("-Z", "Y").to_euler()
    s.camera = cam
    s.render.engine = "CYCLES"
    s.cycles.device = "CPU"
    s.cycles.samples = scene["spp"]
    s.cycles.use_adaptive_sampling = False
    s.cycles.use_denoising = False
    # matseg's one limit on path length, for every kind of bounce (Cycles'
    # defaults would stop diffuse and glossy paths at 4).
    bounces = scene.get("max_bounces", 6)
    s.cycles.max_bounces = bounces
    s.cycles.diffuse_bounces = bounces
    s.cycles.glossy_bounces = bounces
    s.cycles.transmission_bounces = bounces
    s.render.threads_mode = "FIXED"
    s.render.threads = threads
    s.render.resolution_x = scene["width"]
    s.render.resolution_y = scene["height"]
    s.render.resolution_percentage = 100
    s.render.filepath = os.path.join(scene_dir, "cycles.png")
    setup = time.time() - start
    usage = resource.getrusage(resource.RUSAGE_SELF)
    cpu0 = usage.ru_utime + usage.ru_stime
    t0 = time.time()
    bpy.ops.render.render(write_still=True)
    wall = time.time() - t0
    usage = resource.getrusage(resource.RUSAGE_SELF)
    print(json.dumps({
        "blender": bpy.app.version_string,
        "size": scene["width"], "spp": scene["spp"], "threads": threads,
        "setup_seconds": setup, "render_seconds": wall,
        "render_cpu_seconds": usage.ru_utime + usage.ru_stime - cpu0,
        "peak_rss_mib": usage.ru_maxrss / 1024.0,
    }))


if __name__ == "__main__":
    main()
