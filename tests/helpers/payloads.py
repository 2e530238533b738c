"""Hostile policy files for the security tests: each one, if unpickled, creates ``marker``."""
from __future__ import annotations

import base64
import io
import json
import pickle
import zipfile
from pathlib import Path


class _Touch:
    """Unpickling this calls ``open(marker, "w")``: the marker file appears iff the payload ran."""

    def __init__(self, marker: Path):
        self.marker = str(marker)

    def __reduce__(self):
        return (open, (self.marker, "w"))


def sb3_zip(path: Path, marker: Path, *, task: str = "follow_target") -> Path:
    """A stable-baselines3-shaped checkpoint whose cloudpickled ``data`` field runs the payload."""
    blob = base64.b64encode(pickle.dumps(_Touch(marker))).decode()
    data = {"policy_class": {":type:": "<class 'abc.ABCMeta'>", ":serialized:": blob},
            "observation_space": {":type:": "<class 'gymnasium.spaces.box.Box'>", ":serialized:": blob}}
    with zipfile.ZipFile(path, "w") as zf:
        zf.writestr("data", json.dumps(data))
        zf.writestr("policy.pth", pickle.dumps(_Touch(marker)))
        zf.writestr("_stable_baselines3_version", "2.7.0")
    path.with_suffix(".json").write_text(json.dumps({"task": task}))
    return path


def rodlab_zip(path: Path, marker: Path, *, task: str = "follow_target", meta: object = None) -> Path:
    """rodlab's own format (meta.json + policy.pt) whose policy.pt is a pickle running the payload."""
    meta = meta if meta is not None else {
        "format": "rodlab-sac-policy/1", "task": task, "obs_shape": [3], "obs_low": [-1.0] * 3,
        "obs_high": [1.0] * 3, "action_low": [-1.0], "action_high": [1.0], "net_arch": [8], "n_critics": 2}
    buf = io.BytesIO()
    pickle.dump(_Touch(marker), buf)
    with zipfile.ZipFile(path, "w") as zf:
        zf.writestr("meta.json", json.dumps(meta))
        zf.writestr("policy.pt", buf.getvalue())
    return path
