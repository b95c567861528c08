"""A real PostgreSQL server for tests: initdb into a temp dir, pg_ctl start on a free loopback port.

    with postgres_server() as url:      # postgresql+psycopg://postgres@127.0.0.1:PORT/lumenlink
        ...

Uses Debian's server binaries (``/usr/lib/postgresql/<version>/bin``; ``make test`` installs the
``postgresql`` package where it is missing) or an ``initdb`` on the PATH. PostgreSQL refuses to run
as root: as root the server runs as the ``postgres`` user (``runuser``), in a temp dir it owns. It
listens on 127.0.0.1 only, with its unix socket in that dir, trusts local connections, and skips
fsync (a test database). `why_not()` says why no server can be started here, or None.
"""

from __future__ import annotations

import contextlib
import glob
import os
import pwd
import re
import shutil
import subprocess
import tempfile
from collections.abc import Iterator
from pathlib import Path

from service_process import free_port

SUPERUSER = "postgres"
DATABASE = "lumenlink"


def bindir() -> Path | None:
    """The directory of the newest installed server's binaries (initdb, pg_ctl, createdb), or None."""
    found = glob.glob("/usr/lib/postgresql/*/bin/initdb")
    if found:
        def version(path: str) -> tuple[int, ...]:
            return tuple(int(x) for x in re.findall(r"\d+", Path(path).parent.parent.name))
        return Path(max(found, key=version)).parent
    on_path = shutil.which("initdb")
    return Path(on_path).parent if on_path else None


def _run_as() -> list[str] | None:
    """The command prefix that runs a server binary as a user PostgreSQL accepts ([] when not root)."""
    if os.geteuid() != 0:
        return []
    try:
        pwd.getpwnam(SUPERUSER)
    except KeyError:
        return None
    runuser = shutil.which("runuser")
    return [runuser, "-u", SUPERUSER, "--"] if runuser else None


def why_not() -> str | None:
    """Why a server cannot be started here (a sentence), or None if it can."""
    if bindir() is None:
        return ("PostgreSQL's server is not installed (no /usr/lib/postgresql/*/bin/initdb, no initdb on the PATH); "
                "`make test` installs Debian's postgresql package when it runs as root")
    if _run_as() is None:
        return (f"running as root, PostgreSQL must run as the {SUPERUSER!r} user, and there is no such user "
                "or no runuser to switch to it")
    return None


@contextlib.contextmanager
def postgres_server(startup_timeout: int = 60) -> Iterator[str]:
    """Start a throw-away server with one database and yield its SQLAlchemy URL; stop it and delete it after."""
    reason = why_not()
    if reason is not None:
        raise RuntimeError(reason)
    bin_ = bindir()
    assert bin_ is not None
    prefix = _run_as()
    assert prefix is not None
    # not under pytest's tmp dirs: those are private to the user running the tests (mode 0700)
    root = Path(tempfile.mkdtemp(prefix="lumenlink-pg-"))
    if os.geteuid() == 0:
        entry = pwd.getpwnam(SUPERUSER)
        os.chown(root, entry.pw_uid, entry.pw_gid)
    data, log = root / "data", root / "server.log"
    port = free_port()

    def run(*args: str) -> None:
        done = subprocess.run([*prefix, *args], capture_output=True, text=True, timeout=startup_timeout)
        if done.returncode != 0:
            tail = log.read_text(errors="replace")[-3000:] if log.exists() else ""
            raise RuntimeError(f"{' '.join(args)} failed ({done.returncode}):\n{done.stdout}{done.stderr}\n{tail}")

    started = False
    try:
        run(str(bin_ / "initdb"), "-D", str(data), "-U", SUPERUSER, "-A", "trust", "-E", "UTF8", "--locale=C",
            "--no-sync")
        run(str(bin_ / "pg_ctl"), "-D", str(data), "-l", str(log), "-w", "-t", str(startup_timeout),
            "-o", f"-p {port} -k {root} -c listen_addresses=127.0.0.1 -c fsync=off -c max_connections=50",
            "start")
        started = True
        run(str(bin_ / "createdb"), "-h", "127.0.0.1", "-p", str(port), "-U", SUPERUSER, DATABASE)
        yield f"postgresql+psycopg://{SUPERUSER}@127.0.0.1:{port}/{DATABASE}"
    finally:
        if started:
            subprocess.run([*prefix, str(bin_ / "pg_ctl"), "-D", str(data), "-m", "fast", "-w", "stop"],
                           capture_output=True, timeout=60)
        shutil.rmtree(root, ignore_errors=True)
