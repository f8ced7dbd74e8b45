"""The ``bettimill`` console script: the Rust CLI itself, run through the extension module.

Same commands, output and exit codes as the ``bettimill`` binary; the worker processes of
``bettimill build`` are this script again.
"""

import os
import signal
import sys


def main():
    from . import _bettimill

    # The Rust code runs with the GIL released, where Python's own SIGINT handler would
    # only set a flag: restore the default, so Ctrl-C acts as on the binary (commands that
    # handle it themselves, like build, install their own handler).
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    # The file that runs this CLI again (workers of `build`, the scripts of `slurm`): this
    # console script, or under `python -m bettimill` the installed one.
    program = os.path.abspath(sys.argv[0])
    if os.path.basename(program) not in ("bettimill", "bettimill.exe") or not os.path.isfile(program):
        from . import _console_script

        program = _console_script() or program
    return _bettimill.run_cli(["bettimill", *sys.argv[1:]], program)


if __name__ == "__main__":
    sys.exit(main())
