"""`omni-micro study`: sweeps and Monte Carlo of the closed loop and of open-loop moves, run on
Dask (a LocalCluster, or an existing scheduler), one parquet row per run (:mod:`.command`)."""
