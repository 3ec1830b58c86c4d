"""The paper's experiments (Li et al., ICIP 2011, Section 3) on the real data of ../shared/data.

``frisicp bench`` runs them (see :mod:`frisicp_ros.cli.bench`) and writes Markdown tables,
JSON and PNG figures into ``docs/benchmarks/``. Modules, in data-flow order:

- :mod:`.contours` outer contours of MPEG-7 silhouettes (2-D point sets)
- :mod:`.datasets` where the data is, loading the contours, the bunny and bun.conf poses
- :mod:`.cases` case families, the seeded perturbations and the true/reference placement
- :mod:`.reference` the reference placement of two different silhouettes (no true pose exists)
- :mod:`.methods` the compared registration methods behind one signature
- :mod:`.metrics` pose errors, symmetric RMS and the success test
- :mod:`.runner` runs every (family, scale, method) case and collects records
- :mod:`.tables` Markdown tables and JSON
- :mod:`.figures` convergence curves and registration pictures (matplotlib, Agg)
- :mod:`.run` one run: suite -> cases -> report (what ``frisicp bench`` calls)

and for the stand-alone scripts in ``benchmarks/``:

- :mod:`.script` their command line (``--quick`` smoke runs, ``--data``, ``--out``), skips
- :mod:`.report` a scored case, Markdown tables and the report files
- :mod:`.neighbours` counting or replacing the core's nearest-neighbour searches

The data folder: ``--data``, else ``$FRISICP_DATA``, else ``shared/data`` beside the repository
(:func:`.datasets.default_data_dir`, which the scripts in ``benchmarks/`` and the tests use too). Only ``frisicp_core`` is imported: the benchmark needs no ROS.
"""
