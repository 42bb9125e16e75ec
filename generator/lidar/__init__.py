"""Laser scanners (issue #40; docs/lidar.md): a sensor declared once (:mod:`.sensors`: presets
and user-built ones, their emission patterns), the physics of a return (:mod:`.physics`:
range noise, intensity, drop-outs), the sweep cast into the scene's exact triangles over time
(:mod:`.scanner`) and what one sweep gives (:class:`.returns.Scan`). bpy-free (numpy and
open3d); the files are written by exporters/semantickitti.py and exporters/las.py."""
