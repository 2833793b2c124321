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

#: Derivations a parse may evaluate by default (``parse --budget``).  With differentiation, on
#: the development val splits (benchmarks/results/): 1200 gave CMP mIoU 0.513 and RueMonge
#: class-average 0.870 at 1.82–2.06 s per photo on two cores, depending on the machine's
#: state; 1000 gave 0.509 and 0.856 at 1.70–1.78 s in the same state.  The 2 s target is
#: kept with a margin at 1000; both accuracy targets (0.50, 0.80) are met either way.
DEFAULT_BUDGET = 1000
