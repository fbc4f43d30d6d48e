"""Experiment suites for ``unseen eval SUITE``.

Each public module here (a name not starting with ``_``) is one suite with
``run(args) -> int``: ``args.out`` (Path, created), ``args.seed`` (int), ``args.n``
(int or None: how many scenes/runs, the suite's default when None), ``args.workers``
(int), ``args.dask`` (scheduler address or None) and ``args.quick`` (bool: a small
version for CI); the ``pool`` suite also reads ``args.first_seed`` (its seed range), the ``real`` suite
``args.data`` (the folder of real scans, None: ``../shared/data/real``).  A suite builds a list of :class:`eval.runner.Task`, runs them with
:func:`eval.suites._common.run_suite_tasks`, and writes Markdown and CSV tables and
plots under ``args.out`` with the helpers in :mod:`eval.suites._common`.  It returns
0, or 1 when the suite's answer is "no" (e.g. the regression suite got worse).
``unseen eval`` writes ``command.json`` before calling it.
"""
