"""On-disk formats: each format's schema lives here once, shared by its writer and reader.

``FORMAT_VERSION`` versions the whole seed folder (docs/format.md); every HDF5 file and the
manifest carry it. Each per-trajectory export registers its sink beside its format
(``@register_sink``, sinks.py); the first lookup of the sinks imports every module of this
package (generator/registry.py), in every run's driver too: a module here imports without
bpy, and keeps what is slow or has side effects at import (pycolmap, a thread pool) out of
its top level where it can."""

FORMAT_VERSION = "0.5"
# what a reader tells a user whose file has another format version
VERSION_REMEDY = ("update buildee-sites, or regenerate the seed: python -m generator --seeds N --overwrite, "
                  "with the options it was made with")
