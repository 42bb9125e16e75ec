"""On-disk formats: each format's schema lives here once, shared by its writer and reader.

``FORMAT_VERSION`` versions the whole seed folder (docs/format.md); every HDF5 file and the
manifest carry it."""

FORMAT_VERSION = "0.5"
# what a reader tells a user whose file has another format version
VERSION_REMEDY = ("update buildee-sites, or regenerate the seed: python -m generator --seeds N --overwrite, "
                  "with the options it was made with")
