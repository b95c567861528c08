"""Choice of device (issue 27, tracer/gpu/device.py): auto falls back to the CPU with the reason where numba-cuda finds
no GPU, cuda without one is an error (``lumenlink serve --device cuda`` exits 2 saying why), cpu is the CPU."""

from __future__ import annotations

import subprocess
import sys

import pytest

from tracer.gpu.device import DeviceUnavailable, choose, cpu_name, find_cuda


def test_cpu_and_auto():
    assert choose("cpu").kind == "cpu"
    assert cpu_name(2) == "cpu:2 threads"
    name, why = find_cuda()
    dev = choose("auto")
    if name is None:
        assert dev.kind == "cpu" and dev.reason == why and why
    else:
        assert dev.kind == "cuda" and dev.name.startswith("cuda:0")
    with pytest.raises(ValueError):
        choose("gpu")


def test_cuda_without_a_gpu_stops_serve(tmp_path):
    name, why = find_cuda()
    if name is not None:
        pytest.skip(f"a GPU is usable here ({name})")
    with pytest.raises(DeviceUnavailable, match="cuda"):
        choose("cuda")
    r = subprocess.run([sys.executable, "-m", "lumenlink.cli", "serve", "--device", "cuda", "--port", "0",
                        "--data-dir", str(tmp_path)], capture_output=True, text=True, timeout=120)
    assert r.returncode == 2, r.stderr
    assert "device cuda was asked for, but" in r.stderr and why in r.stderr
