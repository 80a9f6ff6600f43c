# Blender (background) script: IN.obj → OUT.obj remeshed by the voxel remesher (a new vertex
# numbering and resolution, as a mesh from another data set would have), triangulated.
# Usage: blender -b --python-exit-code 1 -P remesh_blender.py -- IN.obj OUT.obj VOXEL_SIZE
import sys

import bpy

src, dst, voxel = sys.argv[sys.argv.index("--") + 1:][:3]
bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.ops.wm.obj_import(filepath=src, forward_axis="NEGATIVE_Z", up_axis="Y")
obj = bpy.context.selected_objects[0]
bpy.context.view_layer.objects.active = obj
remesh = obj.modifiers.new("remesh", "REMESH")
remesh.mode = "VOXEL"
remesh.voxel_size = float(voxel)
obj.modifiers.new("triangulate", "TRIANGULATE")
bpy.ops.wm.obj_export(filepath=dst, forward_axis="NEGATIVE_Z", up_axis="Y", apply_modifiers=True,
                      export_selected_objects=False, export_uv=False, export_normals=False,
                      export_materials=False)
