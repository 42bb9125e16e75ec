"""The batch job behind ``python -m generator``: one worker process per seed (worker.py,
imports bpy), run by an executor (executors/: local processes or Ray tasks; both run
executors/seed.py) and driven by a bpy-free runner (runner.py)."""
