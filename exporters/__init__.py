"""On-disk formats: each format's schema lives here once, shared by its writer and reader."""
