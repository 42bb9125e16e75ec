"""The asset catalogue's entries: one module per asset kind or family of kinds, each
declaring its kinds next to their builders and registering them with
:func:`generator.scene.kinds.register`.

Every module here is imported by :func:`generator.scene.kinds.scan` (sorted by name): a new
kind is one new file in this folder and no other edit (docs/scenes.md, "The asset catalogue").
"""

SCANNED = True  # every module of this package is loaded by name (generator/envs/code_key.py reads them all)
