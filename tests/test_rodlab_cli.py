"""The `rodlab` dispatcher: help, unknown commands, and that every table entry names a real function."""
import importlib
import subprocess
import sys
from pathlib import Path

import pytest

import rodlab_cli


def test_help_lists_every_command(capsys):
    assert rodlab_cli.main(["--help"]) == 0
    out = capsys.readouterr().out
    for name in rodlab_cli.COMMANDS:
        assert name in out
    assert "bench" in out


def test_unknown_command_is_a_clear_error(capsys):
    assert rodlab_cli.main(["frobnicate"]) == 2
    assert "unknown command 'frobnicate'" in capsys.readouterr().err


def test_unknown_bench_kind_is_a_clear_error(capsys):
    assert rodlab_cli.main(["bench", "nope"]) == 2
    assert "usage: rodlab bench" in capsys.readouterr().err


@pytest.mark.parametrize("target", [t for t, _ in list(rodlab_cli.COMMANDS.values()) + list(rodlab_cli.BENCH.values())])
def test_every_entry_resolves_to_a_callable(target):
    mod_name, fn_name = target.split(":")
    mod = importlib.import_module(mod_name)
    assert callable(getattr(mod, fn_name))


def test_console_script_runs():
    r = subprocess.run([sys.executable, "-m", "rodlab_cli", "--help"], capture_output=True, text=True, timeout=600)
    assert r.returncode == 0 and "usage: rodlab" in r.stdout


def _with_command(monkeypatch, target: str) -> None:
    monkeypatch.setitem(rodlab_cli.COMMANDS, "probe", (target, "test entry"))


def test_missing_subcommand_module_is_not_available(monkeypatch, capsys):
    _with_command(monkeypatch, "rodlab_no_such_command_module:main")
    assert rodlab_cli.main(["probe"]) == 2
    assert "command is not available" in capsys.readouterr().err


def test_missing_dependency_is_named_not_reported_as_missing_command(monkeypatch, tmp_path, capsys):
    (tmp_path / "rodlab_probe_cmd.py").write_text("import rodlab_absent_dependency_xyz\n\ndef main(argv):\n    return 0\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    _with_command(monkeypatch, "rodlab_probe_cmd:main")
    assert rodlab_cli.main(["probe"]) == 2
    err = capsys.readouterr().err
    assert "'rodlab_absent_dependency_xyz' is not installed" in err and "not available" not in err


def test_broken_import_inside_rodlab_shows_the_error(monkeypatch, tmp_path):
    (tmp_path / "rodlab_probe_cmd2.py").write_text("import sim.no_such_module\n\ndef main(argv):\n    return 0\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    _with_command(monkeypatch, "rodlab_probe_cmd2:main")
    with pytest.raises(ModuleNotFoundError, match="sim.no_such_module"):
        rodlab_cli.main(["probe"])


def test_checkout_benchmarks_say_how_to_run_them_when_not_importable(monkeypatch, tmp_path, capsys):
    """benchmarks/ is not installed: without it `rodlab bench accuracy` says to run it from a checkout's root;
    in a checkout's root it is found there (as `python -m` would)."""
    assert {"accuracy", "fuzz"} <= set(rodlab_cli.CHECKOUT_BENCH) and "sim" not in rodlab_cli.CHECKOUT_BENCH
    real = rodlab_cli.importlib.util.find_spec
    monkeypatch.setattr(rodlab_cli.importlib.util, "find_spec",
                        lambda name, *a: None if name == "benchmarks" else real(name, *a))
    monkeypatch.setattr(sys, "path", list(sys.path))
    monkeypatch.chdir(tmp_path)
    assert rodlab_cli.main(["bench", "accuracy", "--help"]) == 2
    err = capsys.readouterr().err
    assert "runs from a rodlab source checkout" in err and "python -m rodlab_cli bench accuracy" in err
    monkeypatch.chdir(Path(rodlab_cli.__file__).resolve().parent)
    assert rodlab_cli._find_benchmarks() and sys.path[0] == str(Path.cwd())
