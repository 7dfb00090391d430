"""What a run keeps on disk: the league database (``store``, the only SQL) and the run directory (``run_dir``:
opening, locking, checkpoint directories and their manifests)."""
