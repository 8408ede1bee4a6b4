"""`omni-micro study`: sweeps and Monte Carlo of the closed loop and of open-loop moves, run on
Dask (a LocalCluster, or an existing scheduler), one parquet row per run."""

from omni_micro_cli.commands.study.command import add_parser

__all__ = ['add_parser']
