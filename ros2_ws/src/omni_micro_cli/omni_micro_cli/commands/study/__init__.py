"""`omni-micro study`: sweeps and Monte Carlo of the closed loop and of open-loop moves, run on
Dask (a LocalCluster, or an existing scheduler), one parquet row per run (:mod:`.command`).

:mod:`.inputs` (what a run takes and reports), :mod:`.spec` (a study file, checked and expanded),
:mod:`.runs` (one run), :mod:`.execute` (the runs on Dask), :mod:`.report` (summary and figure).
"""
