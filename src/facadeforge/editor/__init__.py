"""The editor (``facadeforge edit``) and the viewer (``facadeforge view``): a local web server
over an OUTDIR or a model file, and the pages it serves (Müller et al. 2007 §5, Fig. 12).

:mod:`.edits` changes a shape tree, :mod:`.session` holds one OUTDIR being edited (undo, redo,
re-derivation, atomic save), :mod:`.scene` turns models and point clouds into what the page
draws, :mod:`.server` serves it all to 127.0.0.1 behind a per-session token.
"""
