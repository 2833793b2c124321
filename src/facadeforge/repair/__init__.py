"""Facade texture repair (seed ``shang2023``): occluders found, labels completed, textures filled.

Arrays in, arrays out; nothing here imports the engine (ARCHITECTURE.md).  Modules:

- ``patchmatch`` / ``complete`` — direction-guided PatchMatch on label maps (§3.2) and a
  label-guided PatchMatch fill of the photo;
- ``structure`` — completion of a label map from its own repetition (hidden windows of a grid);
- ``quilt`` — Efros–Freeman image quilting with the minimum-error boundary cut (§3.4, Alg. 1);
- ``repetition`` — an occluded element filled from its unoccluded instances of the same cluster;
- ``synthesis`` — the label → image network (§3.3), evaluated with numpy;
- ``pipeline`` — :func:`repair`: mask → completed labels → fill by region → repaired photo.
"""
