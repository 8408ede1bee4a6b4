"""How the installed ``omni-micro`` ends (``omni_micro_cli.cli.command``): with main's exit
code, its output whole, every exit hook its modules registered run (the warm-start zygote is
closed by one), and without the interpreter's teardown after that."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

# A command stood in for: it registers an exit hook, as the warm start's zygote does once a
# graph starts, prints without flushing, and returns the code given (or raises SystemExit, as
# --help does inside argparse). A module's object says when the interpreter tears it down.
STAND_IN = textwrap.dedent('''
    import atexit, sys
    from pathlib import Path
    from omni_micro_cli import cli

    class TornDown:
        def __del__(self):
            sys.stderr.write('torn down')

    held = TornDown()

    def stand_in_main():
        atexit.register(Path(sys.argv[1]).write_text, 'closed')
        print('{"result": 1}', end='')
        if sys.argv[2] == 'exit':
            sys.exit(0)
        return int(sys.argv[2])

    cli.main = stand_in_main
    cli.command()
''')


@pytest.mark.parametrize('ending, code', [('3', 3), ('0', 0), ('exit', 0)])
def test_the_command_ends_with_its_code_its_output_whole_and_its_exit_hooks_run(
        ending, code, tmp_path: Path):
    hook = tmp_path / 'hook'
    done = subprocess.run([sys.executable, '-c', STAND_IN, str(hook), ending],
                          capture_output=True, text=True, timeout=60)
    assert (done.returncode, done.stdout) == (code, '{"result": 1}'), done.stderr
    assert hook.read_text() == 'closed'
    # Once main() has returned, nothing is torn down; a command that exits from inside ends as
    # Python ends it.
    assert ('torn down' in done.stderr) == (ending == 'exit'), done.stderr

