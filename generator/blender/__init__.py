"""Everything that touches bpy. Blender's global state is wrapped in :mod:`.session`."""
