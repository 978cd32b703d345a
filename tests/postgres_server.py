"""A throwaway PostgreSQL server on 127.0.0.1 for the tests and the storage benchmark.

The server binaries come from the ``pgserver`` wheel (a dev dependency: no system package,
no network). ``pgserver``'s own API serves on a Unix socket only; the issue asks for TCP on
127.0.0.1, so this drives the wheel's ``initdb`` / ``pg_ctl`` directly. PostgreSQL refuses to
run as root: as root the server runs as the unprivileged user ``pgserver`` creates.
"""

from __future__ import annotations

import os
import shutil
import socket
import subprocess
import tempfile
import time
from pathlib import Path


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class PostgresServer:
    """``with PostgresServer() as pg: pg.url("dbname")``; stopped and deleted on exit."""

    def __init__(self) -> None:
        from pgserver._commands import POSTGRES_BIN_PATH
        self.bin = Path(POSTGRES_BIN_PATH)
        self.root = Path(tempfile.mkdtemp(prefix="gait-tuner-pg-"))
        self.data = self.root / "data"
        self.port = _free_port()
        self.user = None
        if os.geteuid() == 0:
            from pgserver.utils import ensure_user_exists
            self.user = "pgserver"
            ensure_user_exists(self.user)
            import pwd
            pw = pwd.getpwnam(self.user)
            os.chown(self.root, pw.pw_uid, pw.pw_gid)
        os.chmod(self.root, 0o755)

    def _run(self, *args: str, timeout: float = 60) -> None:
        subprocess.run([str(a) for a in args], check=True, capture_output=True, timeout=timeout,
                       user=self.user, cwd=self.root)

    def start(self) -> "PostgresServer":
        self._run(self.bin / "initdb", "-D", self.data, "-U", "postgres", "--auth=trust", "-E", "UTF8")
        opts = f"-h 127.0.0.1 -p {self.port} -k {self.root} -c max_connections=200 -c fsync=off"
        self._run(self.bin / "pg_ctl", "-D", self.data, "-w", "-l", self.root / "log", "-o", opts, "start")
        return self

    def create_database(self, name: str) -> str:
        deadline = time.time() + 30
        while True:
            try:
                self._run(self.bin / "psql", "-h", "127.0.0.1", "-p", str(self.port), "-U", "postgres",
                          "-c", f'CREATE DATABASE "{name}"')
                return self.url(name)
            except subprocess.CalledProcessError:
                if time.time() > deadline:
                    raise
                time.sleep(0.5)

    def url(self, name: str = "postgres") -> str:
        return f"postgresql://postgres@127.0.0.1:{self.port}/{name}"

    def stop(self) -> None:
        try:
            self._run(self.bin / "pg_ctl", "-D", self.data, "-m", "immediate", "stop", timeout=30)
        except (subprocess.SubprocessError, OSError):
            pass
        shutil.rmtree(self.root, ignore_errors=True)

    def __enter__(self) -> "PostgresServer":
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()
