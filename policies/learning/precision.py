"""How a training run's SAC updates are computed: ``Args.precision`` resolved against the machine (docs/training.md,
"Precision").

``precision`` is what a run asks for, ``UpdatePlan`` what it gets:

* ``auto`` (the default): the compiled bfloat16 updates (every layer in bfloat16, each update one ``torch.compile``d
  function; BENCHMARKS.md §6: about half the float32 iteration time, the same learning curve over 7 seeds) when all of
  these hold, else the float32 eager updates, with a one-line notice naming the first that fails: the networks are
  on the CPU, the CPU has bfloat16 instructions (x86 AVX512-BF16 or AMX, Arm BF16), a C++ compiler is on the PATH
  (inductor's CPU back-end), and the run makes enough gradient updates to pay the compile back
  (``MIN_COMPILED_UPDATES``).
* ``bfloat16``: bfloat16 updates, compiled when a compiler is present (eager otherwise, said in the notice).
* ``float32``: the paper's precision, eager (the shipped policies were trained so).

``Args.compile_updates`` (``None`` = as the precision says) and ``Args.bf16_layout`` override the plan's parts.
The compiled code is cached across runs (``configure_compile_cache``), so the first compile is paid once per
machine and torch version.
"""
from __future__ import annotations

import os
import shutil
from dataclasses import asdict, dataclass
from pathlib import Path

__all__ = ["PRECISIONS", "MIN_COMPILED_UPDATES", "UpdatePlan", "cpu_has_bf16", "find_compiler", "plan_updates",
           "configure_compile_cache", "compile_cache_dir"]

PRECISIONS = ("auto", "bfloat16", "float32")

#: fewer gradient updates than this and ``auto`` runs eager float32: the compiled bfloat16 update saves ≈ 23 ms per
#: update on the 2-core test CPU and its first compile costs 45 s (8-10 s from the cache; BENCHMARKS.md §6)
MIN_COMPILED_UPDATES = 3000


@dataclass(frozen=True)
class UpdatePlan:
    """What the updates of a run do (``RodSAC.set_update_settings``) and why, in one line."""

    bf16: bool
    bf16_layout: str
    compiled: bool
    reason: str

    @property
    def label(self) -> str:
        return ("bfloat16" if self.bf16 else "float32") + (" compiled" if self.compiled else " eager")

    def notice(self) -> str:
        return f"updates: {self.label} ({self.reason})"

    def to_json(self) -> dict:
        return {**asdict(self), "label": self.label}


def cpu_has_bf16(cpuinfo: str | None = None) -> bool:
    """Whether this CPU computes bfloat16 products natively: x86 ``avx512_bf16`` / ``amx_bf16`` or Arm ``bf16`` in
    /proc/cpuinfo (``cpuinfo``: its text, for tests). False when it cannot be told (no /proc/cpuinfo)."""
    if cpuinfo is None:
        try:
            cpuinfo = Path("/proc/cpuinfo").read_text(errors="replace")
        except OSError:
            return False
    flags: set[str] = set()
    for line in cpuinfo.splitlines():
        key, _, value = line.partition(":")
        if key.strip().lower() in ("flags", "features"):
            flags.update(value.split())
    return bool(flags & {"avx512_bf16", "amx_bf16", "bf16"})


def find_compiler() -> str | None:
    """The C++ compiler torch.compile's CPU back-end would call ($CXX, g++, c++, clang++), or None."""
    for name in (os.environ.get("CXX", ""), "g++", "c++", "clang++"):
        path = shutil.which(name) if name else None
        if path:
            return path
    return None


def plan_updates(precision: str, *, device: str = "cpu", gradient_updates: int, bf16_layout: str = "all",
                 compile_updates: bool | None = None, bf16_cpu: bool | None = None,
                 compiler: str | None | bool = True) -> UpdatePlan:
    """Resolve ``precision`` (``PRECISIONS``) for a run of ``gradient_updates`` updates on ``device``.

    ``bf16_cpu`` / ``compiler``: what the machine has (``None`` / ``True``: look: ``cpu_has_bf16()``,
    ``find_compiler()``; tests pass them). ``compile_updates``: ``None`` compiles exactly when the plan is
    bfloat16 and a compiler is present; ``True`` asks for it (``ValueError`` without a compiler); ``False`` never.
    Raises ``ValueError`` for an unknown precision."""
    if precision not in PRECISIONS:
        raise ValueError(f"precision must be one of {', '.join(PRECISIONS)}, got {precision!r}")
    if compiler is True:
        compiler = find_compiler()
    if compile_updates and not compiler:
        raise ValueError("compiled updates need a C++ compiler on the PATH (g++, c++ or clang++; set CXX to choose "
                         "one); install one (Debian: apt-get install g++) or train without compiled updates")
    on_cpu = device.split(":")[0] == "cpu"
    if precision == "float32":
        bf16, why = False, "asked for"
    elif precision == "bfloat16":
        bf16, why = True, "asked for"
    elif not on_cpu:
        bf16, why = False, f"precision auto on {device}: the bfloat16 path is measured on CPUs only; " \
                           "--precision bfloat16 asks for it"
    elif not (cpu_has_bf16() if bf16_cpu is None else bf16_cpu):
        bf16, why = False, "this CPU has no bfloat16 instructions (AVX512-BF16, AMX or Arm BF16)"
    elif not compiler:
        bf16, why = False, "no C++ compiler for torch.compile on the PATH; install g++ for the compiled bfloat16 " \
                           "updates (about half the iteration time)"
    elif gradient_updates < MIN_COMPILED_UPDATES and compile_updates is None:
        bf16, why = False, f"a short run ({gradient_updates} updates < {MIN_COMPILED_UPDATES}): compiling would " \
                           "cost more than it saves"
    else:
        bf16, why = True, "this CPU has bfloat16 instructions and a C++ compiler"
    compiled = bool(compiler) and bf16 and on_cpu if compile_updates is None else bool(compile_updates)
    if bf16 and not compiled and compile_updates is None:
        why += "; eager: " + ("no C++ compiler on the PATH" if not compiler else "compiled updates run on CPUs only")
    return UpdatePlan(bf16=bf16, bf16_layout=bf16_layout, compiled=compiled, reason=why)


def compile_cache_dir() -> Path:
    """Where compiled updates are kept between runs: $RODLAB_CACHE_DIR/torchinductor, else
    $XDG_CACHE_HOME/rodlab/torchinductor (~/.cache/rodlab/torchinductor)."""
    base = os.environ.get("RODLAB_CACHE_DIR") or os.path.join(
        os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache"), "rodlab")
    return Path(base) / "torchinductor"


def _torch_default_cache_dir() -> str | None:
    try:
        from torch._inductor.runtime.cache_dir_utils import default_cache_dir
    except ImportError:  # another torch layout: only an unset variable is replaced
        return None
    return os.path.abspath(default_cache_dir())


def configure_compile_cache() -> Path | None:
    """Point inductor's on-disk caches at ``compile_cache_dir()`` (unless TORCHINDUCTOR_CACHE_DIR is set), so a
    compiled update is built once per machine, not once per run (torch's default lives in the temporary folder).
    Must run before torch compiles anything; returns the folder (None when it cannot be made: torch's default)."""
    current = os.environ.get("TORCHINDUCTOR_CACHE_DIR")
    if current and os.path.abspath(current) != _torch_default_cache_dir():  # the user's choice (torch writes its
        return Path(current)                                                 # default there when it first looks)
    path = compile_cache_dir()
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError:
        return None
    os.environ["TORCHINDUCTOR_CACHE_DIR"] = str(path)
    return path
