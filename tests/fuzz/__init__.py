"""Fuzz suite: mutated CGA rules, GeoJSON and OBJ footprints, classifier ``.npz`` files, rule
packages (``.rpk``) and models to render, each run through the command line; every run must end
with exit 0 and valid files, or exit 2 and one ``facadeforge: error: …`` line (oracle.py).

A short run is part of the default ``pytest`` run; ``make fuzz`` runs the long one
(``FACADEFORGE_FUZZ=long``: each run in a forked child, one in ten a fresh
``python -m facadeforge.cli``, bounded to 60 s and 3 GiB; a time budget of
``FACADEFORGE_FUZZ_SECONDS``, default 600, shared by the targets; RNG seed
``FACADEFORGE_FUZZ_SEED``).
"""
