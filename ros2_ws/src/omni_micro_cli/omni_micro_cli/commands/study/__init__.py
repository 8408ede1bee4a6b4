"""`omni-micro study`: sweeps and Monte Carlo of the closed loop and of open-loop moves, run on
Dask (a LocalCluster, or an existing scheduler), one parquet row per run (:mod:`.command`).

The study engine it calls (the file checked and expanded, one run, the runs on Dask, the
summary and figure) is omni_micro_studies'.
"""
