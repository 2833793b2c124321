"""Grammar-driven facade parsing (``simon2011`` ch. 4–5).

- :mod:`.parse` — photo → classifier → (rectification) → search → derived shape tree, labels,
  fitted rules and model (``facadeforge parse``);
- :mod:`.fit` — grammar, energy and search bound together (:func:`~.fit.fit_grammar`);
- :mod:`.layout` — fast 2D derivation of a parse grammar's leaf rectangles;
- :mod:`.energy` — the §4.2.2 segmentation energy through integral images;
- :mod:`.search` — hill climbing (Algorithm 4.1) over the ``@Range``/``@Enum`` parameters;
- :mod:`.evolution` — the evolutionary search of §5.2 (islands, SPEA-II);
- :mod:`.init` — search seeds measured from the classifier's window grid;
- :mod:`.differentiate` — each element instance fitted on its own after the consistent search;
- :mod:`.mrf` — the MRF-Potts baseline of §4.4.1;
- ``grammars/`` — built-in parse grammars: ``grid`` (default), ``haussmann``, ``generic``.
"""

#: Derivations a parse may evaluate by default (``parse --budget``): chosen on the development
#: val splits to keep a parse within its time target with a margin while meeting the accuracy
#: targets (the figures: ``docs/design-measurements.md``; current scores: the ``grammar``
#: benchmark rows).
DEFAULT_BUDGET = 1000
