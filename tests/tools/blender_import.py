# Imports glb files into Blender (run: blender --background --factory-startup --python THIS --
# OUT.json TIME_STEP N_KEYS FILE.glb...) and writes what it made of each: the meshes with their
# "lod" extras, triangles, materials and armature modifiers, the materials' base colour and
# roughness, the armature and the actions; and, for the mesh with lod 0, its evaluated (skinned)
# vertices at each key time k·TIME_STEP s, k < N_KEYS, in glTF's frame and units (metres, +y up)
# as FILE.glb.keyK.f32 (float32 x, y, z per vertex). Used by OutfitLods.BlenderImports*.
import json
import sys

import numpy as np

if not hasattr(np, "bool"):
    np.bool = bool  # Debian's Blender 3.4 glTF importer still uses np.bool, gone in numpy 1.24

import bpy

args = sys.argv[sys.argv.index("--") + 1:]
out_path, step, keys, files = args[0], float(args[1]), int(args[2]), args[3:]
report = []
for path in files:
    bpy.ops.wm.read_factory_settings(use_empty=True)
    result = bpy.ops.import_scene.gltf(filepath=path)
    scene = bpy.context.scene
    objects = list(scene.objects)
    armatures = [o for o in objects if o.type == 'ARMATURE']
    info = {"file": path, "result": sorted(result), "fps": scene.render.fps / scene.render.fps_base,
            "bones": len(armatures[0].data.bones) if armatures else 0, "armatures": len(armatures),
            "actions": [{"name": a.name, "frame_range": list(a.frame_range), "fcurves": len(a.fcurves)}
                        for a in bpy.data.actions], "meshes": [], "materials": []}
    # Blender 3.4 imports a skinned node whose mesh has morph targets (LOD0 with the garment
    # corrections) as an EMPTY with the node's name and extras plus a mesh object named after the
    # glTF mesh ("dressed_LOD0.001", data "dressed_LOD0"): such a mesh takes its empty's "lod".
    empty_lod = {o.name: o.get("lod") for o in objects if o.type == 'EMPTY' and o.get("lod") is not None}
    for o in objects:
        if o.type == 'MESH' and o.get("lod") is None and o.data.name in empty_lod:
            o["lod"] = empty_lod[o.data.name]
    for o in objects:
        if o.type != 'MESH':
            continue
        info["meshes"].append({
            "name": o.name, "lod": o.get("lod"), "shape_keys": len(o.data.shape_keys.key_blocks) if o.data.shape_keys else 0, "triangles": sum(len(p.vertices) - 2 for p in o.data.polygons),
            "vertices": len(o.data.vertices), "materials": [m.name for m in o.data.materials if m],
            "armature_modifiers": sum(m.type == 'ARMATURE' and m.object is not None for m in o.modifiers)})
    for m in bpy.data.materials:
        nodes = m.node_tree.nodes if m.node_tree else []
        bsdf = next((n for n in nodes if n.type == 'BSDF_PRINCIPLED'), None)
        info["materials"].append({
            "name": m.name, "base_color": list(bsdf.inputs["Base Color"].default_value) if bsdf else None,
            "roughness": bsdf.inputs["Roughness"].default_value if bsdf else None})
    lod0 = next((o for o in objects if o.type == 'MESH' and o.get("lod") == 0), None)
    if lod0 is not None:
        for k in range(keys):
            frame = k * step * info["fps"]
            scene.frame_set(int(frame), subframe=frame - int(frame))
            depsgraph = bpy.context.evaluated_depsgraph_get()
            evaluated = lod0.evaluated_get(depsgraph)
            mesh = evaluated.to_mesh()
            world = evaluated.matrix_world
            xyz = np.array([tuple(world @ v.co) for v in mesh.vertices], dtype=np.float64)
            evaluated.to_mesh_clear()
            gltf = np.stack([xyz[:, 0], xyz[:, 2], -xyz[:, 1]], axis=1)  # Blender z-up → glTF y-up
            gltf.astype(np.float32).tofile(f"{path}.key{k}.f32")
    report.append(info)
with open(out_path, "w") as f:
    json.dump(report, f)
