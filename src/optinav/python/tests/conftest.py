"""Shared fixtures of the optinav Python tests (run by ctest: python/eval, python/maploc, ...).

ctest sets PYTHONPATH to build/python (the module), OPTINAV_BIN to the optinav binary and
OPTINAV_SHARED_DATA_DEFAULT to ../shared/data; $OPTINAV_SHARED_DATA overrides the data folder as
for the C++ tests.
"""

import json
import os
import pathlib
import subprocess

import numpy as np
import pytest


def shared_data():
    root = os.environ.get("OPTINAV_SHARED_DATA") or os.environ.get("OPTINAV_SHARED_DATA_DEFAULT")
    if not root:
        root = pathlib.Path(__file__).resolve().parents[4] / ".." / "shared" / "data"
    return pathlib.Path(root).resolve()


DATA = shared_data()


@pytest.fixture(scope="session")
def data():
    return DATA


@pytest.fixture(scope="session")
def optinav_bin():
    path = os.environ.get("OPTINAV_BIN")
    assert path and os.access(path, os.X_OK), "OPTINAV_BIN must name the optinav binary"
    return path


def run_cli(optinav_bin, *args, ok=True):
    """Runs `optinav ARGS`; returns the completed process (exit code checked when ok)."""
    proc = subprocess.run([optinav_bin, *map(str, args)], capture_output=True, text=True,
                          timeout=600)
    if ok:
        assert proc.returncode == 0, proc.stderr
    return proc


def cli_json(optinav_bin, *args):
    """The JSON an `optinav ... --json` command prints."""
    return json.loads(run_cli(optinav_bin, *args).stdout)


def read_pgm(path):
    """A binary 8-bit PGM (P5) as a uint8 array: frames written by render_frame(..., 'x.pgm')."""
    raw = pathlib.Path(path).read_bytes()
    fields, pos = [], 0
    while len(fields) < 4:  # magic, width, height, maxval (no comments in OpenCV's output)
        while raw[pos:pos + 1].isspace():
            pos += 1
        end = pos
        while not raw[end:end + 1].isspace():
            end += 1
        fields.append(raw[pos:end])
        pos = end
    assert fields[0] == b"P5" and fields[3] == b"255", fields
    width, height = int(fields[1]), int(fields[2])
    return np.frombuffer(raw, dtype=np.uint8, count=width * height,
                         offset=pos + 1).reshape(height, width)
