"""Running ``rodlab`` commands in the test's process (the entry point's ``main``, as the console script calls it):
the command's exit code and what it printed, without the seconds a new interpreter spends importing torch and
loading the kernels. tests/test_rodlab_cli.py runs the installed entry point itself."""
from __future__ import annotations

from typing import NamedTuple


class CliResult(NamedTuple):
    returncode: int
    stdout: str
    stderr: str


def rodlab(capsys, *args: str) -> CliResult:
    """``rodlab ARGS`` in this process; ``capsys`` is pytest's fixture (what was printed before is dropped)."""
    import rodlab_cli

    capsys.readouterr()
    try:
        rc = rodlab_cli.main(list(args))
    except SystemExit as exc:  # argparse's refusals
        rc = exc.code if isinstance(exc.code, int) else 2
    out, err = capsys.readouterr()
    return CliResult(int(rc or 0), out, err)
