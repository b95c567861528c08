"""The child process that compiles numba-cuda's kernels to PTX for tests/tracer/gpu/test_gpu_ptx.py.

It takes one core 150-190 s, all of it compilation, and nothing else in the suite waits for it. Run by the worker
that meets the test, it held that worker for three minutes at the end of ``make test`` while the other one idled.
Under ``make test`` (pytest-xdist) the controller starts it instead, before the workers, at the lowest CPU priority
(``nice`` 19): it runs on what the tests leave of the two cores (while they wait on servers, browsers, subprocesses
and compile locks), and the test reads the report it left. Without workers the test runs the child itself.
"""

from __future__ import annotations

import importlib.util
import os
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = ROOT / "tests" / "tracer" / "gpu" / "gpu_ptx_kernels.py"
#: what the child compiles (gpu_ptx_kernels.py's parts): the device functions, the ray kernels, the batch kernels
PARTS = ("sweep", "rays", "batches")
#: the environment variable naming the folder where the controller's child leaves its report
PTX_REPORT = "LUMENLINK_TEST_PTX_REPORT"
#: seconds the child may take, alone on a core or on what the tests leave
TIMEOUT = 1800


def cuda_home() -> str | None:
    """A CUDA toolkit with NVVM and libdevice (``CUDA_HOME``, else /usr/local/cuda*), or None."""
    candidates = [os.environ.get("CUDA_HOME", ""), "/usr/local/cuda", *sorted(map(str, Path("/usr/local").glob(
        "cuda-*")), reverse=True)]
    for c in candidates:
        if c and list(Path(c).glob("nvvm/libdevice/libdevice*.bc")) and (
                list(Path(c).glob("lib*/libnvvm.so*")) or list(Path(c).glob("nvvm/lib64/libnvvm.so*"))):
            return c
    return None


def environment() -> dict[str, str] | str:
    """The child's environment, or why it cannot compile to PTX here (the test's skip reason)."""
    if importlib.util.find_spec("numba_cuda") is None:
        return "numba-cuda is not installed (pip install -e '.[gpu]')"
    home = cuda_home()
    if home is None:
        return "no NVVM/libdevice found (set CUDA_HOME to a CUDA toolkit): cannot compile to PTX"
    return {**os.environ, "CUDA_HOME": home, "NUMBA_FORCE_CUDA_CC": "9.0", "PYTHONPATH": str(ROOT)}


def wanted(args: list[str], root: Path) -> bool:
    """Whether a session over the paths `args` (pytest's, relative to `root`; node ids allowed) runs the PTX check."""
    test = SCRIPT.with_name("test_gpu_ptx.py")
    paths = [(root / a.split("::")[0]).resolve() for a in args] or [root.resolve()]
    return any(test == p or p in test.parents for p in paths)


def start_background() -> subprocess.Popen | None:
    """In the controller: start the child at ``nice`` 19, its output going to a new folder named in the environment
    the workers inherit (`PTX_REPORT`): ``stdout``, ``stderr``, then ``returncode`` once it has ended. None where
    it cannot run here (the test then skips, saying why). The caller stops it (`stop`) when the session ends."""
    env = environment()
    if isinstance(env, str):
        return None
    folder = Path(tempfile.mkdtemp(prefix="lumenlink-ptx-"))
    with open(folder / "stdout", "wb") as out, open(folder / "stderr", "wb") as err:
        proc = subprocess.Popen([sys.executable, str(SCRIPT), *PARTS], env=env, cwd=ROOT, stdout=out, stderr=err,
                                preexec_fn=lambda: os.nice(19))

    def wait() -> None:
        try:
            code = proc.wait(timeout=TIMEOUT)
        except subprocess.TimeoutExpired:
            proc.kill()
            code = f"timed out after {TIMEOUT} s"
        partial = folder / "returncode.partial"
        partial.write_text(str(code))
        partial.replace(folder / "returncode")

    threading.Thread(target=wait, name="lumenlink-ptx-child", daemon=True).start()
    os.environ[PTX_REPORT] = str(folder)
    return proc


def stop(proc: subprocess.Popen | None) -> None:
    """End the child where it still runs (a session that ended, or was interrupted, before it did)."""
    if proc is not None and proc.poll() is None:
        proc.kill()
        proc.wait(timeout=30)


def run() -> tuple[str, str, str]:
    """(returncode, stdout, stderr) of the child: the controller's, once it has ended, where it started one;
    else the child run here and now. Raises RuntimeError (the reason) where no child can run here."""
    folder = os.environ.get(PTX_REPORT)
    if folder:
        done = Path(folder) / "returncode"
        deadline = time.monotonic() + TIMEOUT
        while not done.exists() and time.monotonic() < deadline:
            time.sleep(1.0)
        if not done.exists():
            return f"no report after {TIMEOUT} s", "", ""
        return (done.read_text(), (Path(folder) / "stdout").read_text(), (Path(folder) / "stderr").read_text())
    env = environment()
    if isinstance(env, str):
        raise RuntimeError(env)
    r = subprocess.run([sys.executable, str(SCRIPT), *PARTS], env=env, cwd=ROOT, capture_output=True, text=True,
                       timeout=TIMEOUT)
    return str(r.returncode), r.stdout, r.stderr
