"""A PostgreSQL server of our own, from Debian's `postgresql` binaries (for the tests and a local
`make fleet`): `initdb` and `pg_ctl` in a folder, on 127.0.0.1 and a port of its own, its
socket in that folder, clients of this machine trusted without a password.

PostgreSQL refuses to run as root: started by root, the server runs as the `postgres` user that
Debian's package makes (the folder is then given to it, and must be reachable by it).
"""

import getpass
import glob
import os
import pwd
import shutil
import subprocess
from pathlib import Path

from task_manager_mqtt.broker import free_port

START_TIMEOUT_SEC = 60
SERVER_USER = 'postgres'
"""Who runs the server when root starts it."""
READY_LINE = 'database system is ready to accept connections'
"""What the server logs once it answers (on stderr, when it runs in the foreground)."""
RANDOM_PAGE_COST = 1.1
"""The planner's cost of reading a page out of order, for a solid-state disk (PostgreSQL's 4.0
is a spinning disk's). With 4.0, a history query filtered by a source none of the newest
results have read the newest first and filtered them (18 ms at 1,000,000 results), rather than
the source's own index (0.3 ms)."""


class PostgresError(RuntimeError):
    """The server could not be made, started or stopped; the message says why."""


def postgres_bin() -> Path:
    """The folder of `initdb` and `pg_ctl`: on the PATH, else Debian's newest version's."""
    found = shutil.which('initdb')
    if found:
        return Path(found).resolve().parent
    versions = sorted(
        glob.glob('/usr/lib/postgresql/*/bin/initdb'),
        key=lambda p: int(Path(p).parts[-3]) if Path(p).parts[-3].isdigit() else 0,
    )
    if not versions:
        raise PostgresError(
            "no initdb: install Debian's postgresql package (make install does where it is missing)"
        )
    return Path(versions[-1]).parent


class PostgresServer:
    """One server; `start()` makes its cluster the first time, `stop()` keeps its data."""

    def __init__(self, folder: Path, port: int = 0, user: str = 'console') -> None:
        """`folder`: where its data, socket and log live. `user`: the database's owner, the
        user of `url` (trusted, no password)."""
        self.folder = folder.absolute()
        self.port = port or free_port()
        self.user = user
        self.bin = postgres_bin()
        self._as_root = os.geteuid() == 0

    @property
    def data(self) -> Path:
        return self.folder / 'data'

    @property
    def log_file(self) -> Path:
        return self.folder / 'postgresql.log'

    def url(self, database: str = 'postgres') -> str:
        """A URL of a database on it, for SQLAlchemy, the console and `psql` alike."""
        return f'postgresql://{self.user}@127.0.0.1:{self.port}/{database}'

    def start(self) -> None:
        """Make the cluster if it is new, then start the server and wait until it answers."""
        self.make_cluster()
        self._run(
            'pg_ctl',
            'start',
            '--pgdata',
            str(self.data),
            '--log',
            str(self.log_file),
            '--wait',
            '--timeout',
            str(START_TIMEOUT_SEC),
            '-o',
            self._server_options(),
        )

    def make_cluster(self, database: str = '') -> None:
        """Make the cluster if it is new, with `database` too (if given), without starting it."""
        self.folder.mkdir(parents=True, exist_ok=True)
        if self._as_root:
            account = pwd.getpwnam(SERVER_USER)
            os.chown(self.folder, account.pw_uid, account.pw_gid)
        if not (self.data / 'PG_VERSION').exists():
            self._run(
                'initdb',
                '--pgdata',
                str(self.data),
                '--username',
                self.user,
                '--auth',
                'trust',
                '--encoding',
                'UTF8',
                '--locale',
                'C',
            )
            if database:  # single-user mode: no server runs yet
                self._run(
                    'postgres',
                    '--single',
                    '-D',
                    str(self.data),
                    'postgres',
                    stdin=f'CREATE DATABASE "{database}"\n',
                )

    @property
    def command(self) -> list[str]:
        """The server's command line in the foreground (its log on stderr, READY_LINE once it
        answers; SIGINT: a fast shutdown), after `make_cluster`. SIGTERM is its parent-death
        signal (setpriv sets it, then execs the server: the signals reach the server itself):
        it ends with the process that started it, however that ends. As root, it runs as
        SERVER_USER, switched to by the same exec."""
        server = [str(self.bin / 'postgres'), '-D', str(self.data), *self._server_options().split()]
        switch = ['--reuid', SERVER_USER, '--regid', SERVER_USER, '--init-groups']
        return ['setpriv', *(switch if self._as_root else []), '--pdeathsig', 'TERM', *server]

    def _server_options(self) -> str:
        return (
            f'-p {self.port} -k {self.folder} -c listen_addresses=127.0.0.1 '
            f'-c random_page_cost={RANDOM_PAGE_COST}'
        )

    def stop(self) -> None:
        """A fast shutdown (sessions ended, data kept); nothing if it is not running."""
        if (self.data / 'postmaster.pid').exists():
            self._run('pg_ctl', 'stop', '--pgdata', str(self.data), '--mode', 'fast', '--wait')

    def create_database(self, name: str) -> str:
        """Create a database on the running server; its URL."""
        self._run(
            'createdb', '--host', '127.0.0.1', '--port', str(self.port), '-U', self.user, name
        )
        return self.url(name)

    def _run(self, program: str, *args: str, stdin: str | None = None) -> None:
        command = [str(self.bin / program), *args]
        if self._as_root:
            command = ['runuser', '-u', SERVER_USER, '--', *command]
        done = subprocess.run(
            command,
            input=stdin,
            capture_output=True,
            text=True,
            check=False,
            timeout=START_TIMEOUT_SEC + 30,
        )
        if done.returncode != 0:
            output = (done.stderr or done.stdout).strip().splitlines()
            log = self.log_file.read_text()[-2000:] if self.log_file.exists() else ''
            user = SERVER_USER if self._as_root else getpass.getuser()
            raise PostgresError(
                f'{program} failed ({done.returncode}) as {user}: '
                + ' / '.join(output[-5:])
                + (f'\nserver log:\n{log}' if log else '')
            )
