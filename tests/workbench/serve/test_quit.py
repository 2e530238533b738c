"""Ctrl-C and SIGTERM end the workbench even when the signal lands inside a finaliser that swallows exceptions
(as while the stepping thread compiles the kernels on a first start: a KeyboardInterrupt raised there was lost and
the workbench ran on)."""
from __future__ import annotations

import subprocess
import sys

import pytest

from tests.helpers.paths import REPO

SCRIPT = """
import os, signal, sys
from workbench.serve.cli import QuitOnSignal

signum = getattr(signal, sys.argv[1])


class Swallows:
    def __del__(self):
        try:
            os.kill(os.getpid(), signum)  # handled right here, inside the finaliser
            for _ in range(1000):
                pass
        except BaseException:
            print("swallowed", flush=True)


with QuitOnSignal() as asked:
    Swallows()  # dropped at once: its finaliser runs in the main thread
    print("asked" if asked else "lost", flush=True)
print("restored" if signal.getsignal(signal.SIGINT) is signal.default_int_handler else "not restored")
"""


@pytest.mark.parametrize("sig", ["SIGINT", "SIGTERM"])
def test_a_signal_inside_a_swallowing_finaliser_still_asks_to_quit(sig):
    out = subprocess.run([sys.executable, "-c", SCRIPT, sig], cwd=REPO, capture_output=True, text=True,
                         timeout=600)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["asked", "restored"], out.stdout + out.stderr


def test_a_second_ctrl_c_interrupts_the_stop():
    script = ("import os, signal\nfrom workbench.serve.cli import QuitOnSignal\n"
              "with QuitOnSignal() as asked:\n"
              "    os.kill(os.getpid(), signal.SIGINT)\n"
              "    assert asked\n"
              "    try:\n"
              "        os.kill(os.getpid(), signal.SIGINT)\n"
              "        for _ in range(1000): pass\n"
              "    except KeyboardInterrupt:\n"
              "        print('interrupted')\n")
    out = subprocess.run([sys.executable, "-c", script], cwd=REPO, capture_output=True, text=True, timeout=600)
    assert out.returncode == 0 and out.stdout.strip() == "interrupted", out.stdout + out.stderr
