"""Scoring masks against CDnet 2014 ground truth, comparing methods, and timing them.

- :mod:`~bgsub.evaluation.cdnet`: ``evaluate``/``evaluate_sequence``/``evaluate_dataset``, the
  CDnet conventions (its docstring), and every public name of the modules below.
- :mod:`~bgsub.evaluation.metrics`: ``Counts``, ``Metrics``, ``count_frame``.
- :mod:`~bgsub.evaluation.groundtruth`: ``GroundTruth`` of a sequence, finding sequences.
- :mod:`~bgsub.evaluation.predictions`: one ``PredictionReader`` per kind of prediction (mask
  folder, mask video, masks from Python).
- :mod:`~bgsub.evaluation.scoring`: ``SequenceScorer`` (where masks meet ground truth) and
  ``GroundTruthScorer``, its consumer of the frame loop (:mod:`bgsub.io.loop`).
- :mod:`~bgsub.evaluation.results`: per-sequence/category/overall results and their tables.
- :mod:`~bgsub.evaluation.compare`: ``compare_methods`` (`bgsub compare`), with
  :mod:`~bgsub.evaluation.compare_job` (one input through the frame loop),
  :mod:`~bgsub.evaluation.compare_report`, :mod:`~bgsub.evaluation.side_by_side` and
  :mod:`~bgsub.evaluation.report_dir`.
- :mod:`~bgsub.evaluation.bench`: ``bench_methods`` (`bgsub bench`).
"""
