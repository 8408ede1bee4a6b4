"""Where the workspace's packages are installed (``AMENT_PREFIX_PATH``, else this Python's
prefix, where pip puts them), and the files they install: the Fast DDS profile of the graph,
which a node names when it tells the user to export it and a command's own participants use."""

from __future__ import annotations

import os
import sys
from pathlib import Path


def install_prefixes() -> list[Path]:
    prefixes = os.environ.get('AMENT_PREFIX_PATH', sys.prefix).split(os.pathsep)
    return [Path(p) for p in prefixes if p]


def installed_file(package: str, *parts: str) -> Path | None:
    """``<prefix>/share/<package>/<parts...>`` under the first prefix that has it."""
    for prefix in install_prefixes():
        path = prefix.joinpath('share', package, *parts)
        if path.is_file():
            return path
    return None


def dds_profile_file() -> Path | None:
    """The project's Fast DDS profile (installed with omni_micro_common), or None."""
    return installed_file('omni_micro_common', 'config', 'fastdds.xml')


def use_dds_profile() -> None:
    """This process's DDS participants on the project's Fast DDS profile, unless the user named
    one (``FASTRTPS_DEFAULT_PROFILES_FILE``): rmw_fastrtps reads it as the process makes each
    participant. Among what it sets (config/fastdds.xml), Fast DDS's own errors go to standard
    error: by default it prints them on standard output, ahead of a ``--json`` document."""
    profile = dds_profile_file()
    if profile is not None:
        os.environ.setdefault('FASTRTPS_DEFAULT_PROFILES_FILE', str(profile))


def dds_profile_to_export() -> str | None:
    """The profile a driver should be given: the one this process runs with (a run gives
    every node the project's), else the installed one; None when neither is known."""
    path = os.environ.get('FASTRTPS_DEFAULT_PROFILES_FILE') or dds_profile_file()
    return str(path) if path else None
