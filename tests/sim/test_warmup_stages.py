"""sim.warmup names each kernel group it compiles and how far along it is (the workbench's status line shows it
while the page waits on a first start)."""
from __future__ import annotations

from sim.warmup import STAGES, compile_kernels


def test_each_stage_is_named_with_its_count():
    seen: list[str] = []
    compile_kernels(on_stage=seen.append)
    assert len(seen) == STAGES == 4
    assert [s.rsplit("(", 1)[1] for s in seen] == [f"stage {k} of 4)" for k in (1, 2, 3, 4)]
    assert seen[0].startswith("the 3D step kernel") and seen[2].startswith("the 2D step kernel")
