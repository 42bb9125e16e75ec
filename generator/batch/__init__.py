"""The batch job behind ``python -m generator``: one worker process per seed (worker.py,
imports bpy) driven by a bpy-free runner (runner.py)."""
