# shellcheck shell=bash
# Sourced by every command in scripts/: brings the project venv in line with requirements.lock and
# the workspace sources, then sets the environment every process of the project runs in.
#
# First use creates .venv from the lock (about a minute); later calls only compare two hashes.

OMNI_MICRO_ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)
OMNI_MICRO_VENV=${OMNI_MICRO_VENV:-$OMNI_MICRO_ROOT/.venv}
# Every package of the workspace, installed into the venv as colcon would build them.
OMNI_MICRO_PACKAGES=(omni_micro_common omni_micro_sim omni_micro_vision omni_micro_control
                     omni_micro_tools omni_micro_studies omni_micro_bringup omni_micro_cli)

_omni_micro_log() { printf 'omni-micro: %s\n' "$*" >&2; }

_omni_micro_base_python() {
    local candidate
    for candidate in "${OMNI_MICRO_PYTHON:-}" python3.11 python3; do
        [ -n "$candidate" ] || continue
        command -v "$candidate" >/dev/null 2>&1 || continue
        if "$candidate" -c 'import sys; sys.exit(sys.version_info[:2] != (3, 11))'; then
            echo "$candidate"
            return 0
        fi
    done
    _omni_micro_log "no Python 3.11 found (the ROS 2 Jazzy wheels need it); set OMNI_MICRO_PYTHON"
    return 1
}

_omni_micro_sources_hash() {
    # Sources of the workspace packages: a change reinstalls them (a normal install, because editable
    # installs drop data_files such as config/*.yaml and the ament index markers).
    (cd "$OMNI_MICRO_ROOT" && find ros2_ws/src -type f \
        -not -path '*/__pycache__/*' -not -path '*.egg-info*' -not -name '*.pyc' -print0 \
        | sort -z | xargs -0 sha256sum | sha256sum | cut -c1-64)
}

omni_micro_ensure_venv() {
    local lock_hash stamp python
    lock_hash=$(sha256sum "$OMNI_MICRO_ROOT/requirements.lock" | cut -c1-64)
    stamp="$OMNI_MICRO_VENV/.omni-micro-lock"
    if [ ! -x "$OMNI_MICRO_VENV/bin/python" ] || [ "$(cat "$stamp" 2>/dev/null)" != "$lock_hash" ]; then
        python=$(_omni_micro_base_python) || return 1
        _omni_micro_log "creating the project venv at $OMNI_MICRO_VENV from requirements.lock (first use: about a minute)"
        rm -rf "$OMNI_MICRO_VENV"
        "$python" -m venv "$OMNI_MICRO_VENV" || return 1
        "$OMNI_MICRO_VENV/bin/python" -m pip install --quiet --no-deps \
            -r "$OMNI_MICRO_ROOT/requirements.lock" 2> >(grep -v "^WARNING: Location" >&2) || {
            _omni_micro_log "installing requirements.lock failed; the venv is left incomplete and is rebuilt next time"
            return 1
        }
        echo "$lock_hash" > "$stamp"
        rm -f "$OMNI_MICRO_VENV/.omni-micro-sources"
    fi
    local sources_hash
    sources_hash=$(_omni_micro_sources_hash)
    if [ "$(cat "$OMNI_MICRO_VENV/.omni-micro-sources" 2>/dev/null)" != "$sources_hash" ]; then
        _omni_micro_log "installing the workspace packages into the venv"
        local package_dirs=()
        local package
        for package in "${OMNI_MICRO_PACKAGES[@]}"; do
            package_dirs+=("$OMNI_MICRO_ROOT/ros2_ws/src/$package")
        done
        "$OMNI_MICRO_VENV/bin/python" -m pip install --quiet --no-deps --no-build-isolation \
            --force-reinstall "${package_dirs[@]}" 2> >(grep -v "^WARNING: Location" >&2) || return 1
        # pip builds in place: leave the source tree as clean as it was.
        rm -rf "$OMNI_MICRO_ROOT"/ros2_ws/src/*/build "$OMNI_MICRO_ROOT"/ros2_ws/src/*/*.egg-info
        echo "$sources_hash" > "$OMNI_MICRO_VENV/.omni-micro-sources"
    fi
}

omni_micro_export_env() {
    # DDS must never leave loopback: every process of the project inherits this.
    export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST
    unset ROS_LOCALHOST_ONLY
    export RMW_IMPLEMENTATION=rmw_fastrtps_cpp
    export AMENT_PREFIX_PATH="$OMNI_MICRO_VENV"
    export MPLBACKEND=Agg
    # numpy's OpenBLAS on one thread, as omni-micro gives its nodes (omni_micro_bringup.processes,
    # SINGLE_THREADED_BLAS, says why), for every process of the scripts and the tests.
    export OPENBLAS_NUM_THREADS="${OPENBLAS_NUM_THREADS:-1}"
    export PATH="$OMNI_MICRO_VENV/bin:$PATH"
    export OMNI_MICRO_ROOT OMNI_MICRO_VENV
}
