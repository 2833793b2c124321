"""Grammar-driven facade parsing (``simon2011`` ch. 4–5).

- :mod:`.layout` — fast 2D derivation of a parse grammar's leaf rectangles;
- :mod:`.energy` — the §4.2.2 segmentation energy through integral images;
- :mod:`.search` — the procedural space (``@Range``/``@Enum`` attributes) and hill climbing
  (Algorithm 4.1);
- :mod:`.fit` — grammar + energy + search bound together (:func:`~.fit.fit_grammar`);
- :mod:`.mrf` — the MRF-Potts baseline of §4.4.1;
- ``grammars/`` — built-in parse grammars (``generic``).
"""
