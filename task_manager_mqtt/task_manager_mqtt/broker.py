"""A local mosquitto of our own (Debian's `mosquitto`), for the tests, `make fleet` and the bench.

On 127.0.0.1 only, with an account per robot and one for the cloud (or several), maybe read-only
observers, and an ACL that lets a robot read only its own requests and write only its own
outgoing topics (reply, result, ...), the cloud read those of every robot and write only their
requests, and an observer read every topic under the prefix and write none. The
broker takes each client's id from its account (`use_username_as_clientid`), so that no
account can connect as another's client and push it off. Its sessions and queued messages
persist across a restart (stop() then start() again), as a production broker's should.
"""

import getpass
import secrets
import shutil
import socket
import subprocess
from collections.abc import Sequence
from pathlib import Path

from task_manager_mqtt.settings import (
    DEFAULT_MAX_PAYLOAD_BYTES,
    DEFAULT_PREFIX,
    PACKET_HEADROOM_BYTES,
)
from task_manager_mqtt.topics import ANY_ROBOT, OUTGOING, Topics

CLOUD_USER = 'cloud'
OBSERVER_USER = 'observer'
"""The usual name of a read-only account (mosquitto_sub and other watchers)."""
READY_LINE = r'mosquitto version \S+ running'
MAX_QUEUED_MESSAGES = 100_000
"""Per client, while it is away (mosquitto's default, 1,000, would drop a long outage's)."""


def mosquitto_executable() -> str:
    return shutil.which('mosquitto') or '/usr/sbin/mosquitto'


def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(('127.0.0.1', 0))
        port: int = probe.getsockname()[1]
        return port


class MosquittoBroker:
    def __init__(
        self,
        folder: Path,
        robots: Sequence[str],
        prefix: str = DEFAULT_PREFIX,
        port: int = 0,
        tls: bool = False,
        clouds: Sequence[str] = (CLOUD_USER,),
        max_payload_bytes: int = DEFAULT_MAX_PAYLOAD_BYTES,
        observers: Sequence[str] = (),
    ) -> None:
        """`tls`: listen with TLS only, with a certificate of a CA of its own (`ca_file`).
        `clouds`: the cloud's accounts (one per process of the cloud that connects).
        `observers`: read-only accounts, which read every topic under the prefix.
        `max_payload_bytes`: the largest message it passes on (the bridges' limit)."""
        self.folder = folder
        self.prefix = prefix
        self.port = port or free_port()
        self.tls = tls
        self.max_payload_bytes = max_payload_bytes
        self.ca_file: Path | None = None
        self.robots = list(robots)
        self.clouds = list(clouds)
        self.observers = list(observers)
        accounts = (*clouds, *observers, *robots)
        self.passwords = {user: secrets.token_urlsafe(12) for user in accounts}
        self._write_files()

    def url(self, user: str = CLOUD_USER) -> str:
        scheme = 'mqtts' if self.tls else 'mqtt'
        return f'{scheme}://{user}:{self.passwords[user]}@127.0.0.1:{self.port}'

    @property
    def command(self) -> list[str]:
        """The broker's command line (which logs READY_LINE once it listens)."""
        return [mosquitto_executable(), '-c', str(self.folder / 'mosquitto.conf')]

    def _write_files(self) -> None:
        self.folder.mkdir(parents=True, exist_ok=True)
        passwords = self.folder / 'passwords'
        passwords.write_text('')
        passwords.chmod(0o600)
        for user, password in self.passwords.items():
            subprocess.run(
                ['mosquitto_passwd', '-b', str(passwords), user, password],
                check=True,
                capture_output=True,
            )
        (self.folder / 'acl').write_text(self.acl())
        (self.folder / 'mosquitto.conf').write_text(
            f'listener {self.port} 127.0.0.1\n'
            # run as whoever started it (as root, mosquitto would switch to its own user)
            f'user {getpass.getuser()}\n'
            f'allow_anonymous false\n'
            f'password_file {passwords}\n'
            f'acl_file {self.folder / "acl"}\n'
            f'set_tcp_nodelay true\n'
            # a client's id is its user name: robot2's account connecting as robot1's client
            # would otherwise disconnect robot1's bridge (the broker drops the older connection)
            f'use_username_as_clientid true\n'
            f'persistence true\n'
            f'persistence_location {self.folder}/\n'
            f'max_queued_messages {MAX_QUEUED_MESSAGES}\n'
            # MQTT 5 clients learn it from the CONNACK; one that sends a larger packet is
            # disconnected and its message never delivered. (message_size_limit would drop
            # the message with a PUBACK of reason 0x95, which paho takes for a malformed packet)
            f'max_packet_size {self.max_payload_bytes + PACKET_HEADROOM_BYTES}\n'
            f'log_dest stderr\n'  # unbuffered: each line as it is written
            f'log_timestamp false\n' + self._tls_lines()
        )

    def acl(self) -> str:
        """The ACL file: user by user, no `pattern` lines (they apply to every account)."""
        every_robot = Topics(self.prefix, ANY_ROBOT)
        lines = ['# the cloud: reads what every robot sends, writes only their requests']
        for user in self.clouds:
            lines += [f'user {user}', *(f'topic read {every_robot.topic(n)}' for n in OUTGOING)]
            lines += [f'topic write {every_robot.request}', '']
        if self.observers:
            lines += ['# an observer: reads every topic under the prefix, writes none']
        for user in self.observers:
            lines += [f'user {user}', f'topic read {self.prefix}/#', '']
        lines += ['# a robot (user name = robot id): reads its requests, writes what it sends']
        for robot_id in self.robots:
            own = Topics(self.prefix, robot_id)
            lines += [f'user {robot_id}', f'topic read {own.request}']
            lines += [*(f'topic write {own.topic(name)}' for name in OUTGOING), '']
        return '\n'.join(lines)

    def _tls_lines(self) -> str:
        if not self.tls:
            return ''
        from task_manager_mqtt.certificates import write_broker_certificates  # tests only

        self.ca_file, certificate, key = write_broker_certificates(self.folder)
        return f'cafile {self.ca_file}\ncertfile {certificate}\nkeyfile {key}\n'
