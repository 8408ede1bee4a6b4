"""An entry point for warm_start's tests: prints what the process it runs in was given, then
does what its last argument says (exit with a code, raise, use 0.3 s of CPU, wait for a
signal or for its lifeline's end)."""

import ctypes
import json
import os
import signal
import sys
import time
from pathlib import Path


def main() -> int:
    fds = {int(name) for name in os.listdir('/proc/self/fd')}
    lifeline = int(os.environ.get('PROBE_LIFELINE_FD', '-1'))
    # Imported and compiled before the probe ran: what the process it runs in had done.
    integrator = sys.modules.get('omni_micro_sim.integrator')
    compiled = sum(len(kernel.signatures) for kernel in vars(integrator).values()
                   if hasattr(kernel, 'signatures')) if integrator else 0
    print(json.dumps({
        'argv': sys.argv, 'cwd': os.getcwd(), 'domain': os.environ.get('ROS_DOMAIN_ID'),
        'own_session': os.getsid(0) == os.getpid(), 'pid': os.getpid(),
        'name': Path('/proc/self/comm').read_text().strip(),
        'cmdline': Path('/proc/self/cmdline').read_text().rstrip('\0').replace('\0', ' '),
        # What rcutils names a ROS log file by.
        'invocation': (ctypes.c_char_p.in_dll(ctypes.CDLL(None), 'program_invocation_name')
                       .value or b'').decode(),
        'open_fds': sorted(fds), 'lifeline_open': lifeline in fds,
        'stdin_is_null': os.path.samefile('/proc/self/fd/0', os.devnull),
        'compiled_kernels': compiled,
    }), flush=True)
    what = sys.argv[-1]   # after a node's ROS arguments, when it is given them
    if what == 'raise':
        raise RuntimeError('the probe fails as asked')
    if what == 'wait':
        print('waiting', flush=True)
        os.read(lifeline, 1)   # returns at end-of-file: the orchestrator has gone
        return 0
    if what == 'spin':
        until = time.process_time() + 0.3
        while time.process_time() < until:
            pass
        return 0
    if what == 'sleep':
        print('waiting', flush=True)
        while True:
            signal.pause()
    return int(what)


if __name__ == '__main__':
    sys.exit(main())
