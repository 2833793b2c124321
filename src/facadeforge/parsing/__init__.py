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

#: Derivations a parse may evaluate by default (``parse --budget``): on the RueMonge validation
#: photos the evolutionary search reached class-average 0.80 at 1000 and 0.81–0.83 at 1200
#: (three seeds, before differentiation; 0.833 with it), at under 2 s per photo on two cores
#: (benchmarks/results/).  On CMP, 1400 instead of 1200 changed mIoU by −0.006 and +0.004 on two
#: resamplings of the same probabilities: noise, not worth the time.
DEFAULT_BUDGET = 1200
