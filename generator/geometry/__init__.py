"""bpy-free geometry shared by the simulator, the exporters and the evaluation.

Everything in this subpackage uses numpy (and open3d for ray casting) only, so that
`evaluation/` and `datasets/` can reuse the exact same conventions without Blender.
"""
