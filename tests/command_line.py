"""The command line run in-process, as a test helper.

typer's CliRunner goes through the same path as `ph-explorer ...` (the typer app, the one wrapper that
turns bad input into one line and exit 2), without starting an interpreter and importing torch per
call. The tests of the process itself (`python -m`, the script, imports without torch, Ctrl-C,
serve) start real processes: tests/test_cli.py, tests/test_loading.py.
"""

from __future__ import annotations

import subprocess

from typer.testing import CliRunner

from ph_explorer.cli import app


def run_cli(*args: str) -> subprocess.CompletedProcess[str]:
    """`ph-explorer ARGS` in this process: its exit status, stdout and stderr, as a finished process."""
    result = CliRunner().invoke(app, [str(a) for a in args], env={"COLUMNS": "120"})
    if result.exception is not None and not isinstance(result.exception, SystemExit):
        raise result.exception  # a traceback in the command, shown as the test's failure
    return subprocess.CompletedProcess(list(args), result.exit_code, result.stdout, result.stderr)
