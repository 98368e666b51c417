"""What the bridge and the FleetClient need to reach a broker, from a URL, arguments or YAML.

A broker URL is `mqtt://[user[:password]@]host[:port]` (1883 by default), or `mqtts://`
for TLS (8883 by default).
"""

import logging
import os
from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from typing import Any
from urllib.parse import unquote, urlsplit

import yaml

from task_manager.cpu_priority import GATEWAY_NICENESS, MAX_NICENESS, is_niceness
from task_manager.gateway.secret_file import exposure_warning

DEFAULT_PREFIX = 'task_manager/v1'
DEFAULT_PORTS = {'mqtt': 1883, 'mqtts': 8883}
TOPIC_FORBIDDEN = ('+', '#', '/')
DEFAULT_MAX_PAYLOAD_BYTES = 1_048_576
"""The largest request the bridge accepts and message it sends; the broker's limit too."""
PACKET_HEADROOM_BYTES = 1024
"""What an MQTT packet here adds to its payload, at most: fixed header, topic, properties."""


class SettingsError(ValueError):
    """A setting that cannot be used; the message names it."""


@dataclass(frozen=True)
class Tls:
    ca_file: str = ''
    """Certificate authorities to trust; empty: the system's."""
    cert_file: str = ''
    """A client certificate, with key_file, when the broker asks for one."""
    key_file: str = ''
    insecure: bool = False
    """Do not check the broker's host name (tests only)."""


@dataclass(frozen=True)
class Broker:
    """Where and as whom to connect."""

    host: str = '127.0.0.1'
    port: int = 1883
    username: str = ''
    password: str = ''
    tls: Tls | None = None

    @classmethod
    def from_url(cls, url: str, tls: Tls | None = None) -> 'Broker':
        parts = urlsplit(url)
        if parts.scheme not in DEFAULT_PORTS or not parts.hostname:
            raise SettingsError(
                f'broker URL {url!r}: expected mqtt://[user[:password]@]host[:port] or mqtts://...'
            )
        try:
            port = parts.port or DEFAULT_PORTS[parts.scheme]
        except ValueError as error:
            raise SettingsError(f'broker URL {url!r}: {error}') from None
        if parts.scheme == 'mqtt' and tls is not None:
            raise SettingsError(f'broker URL {url!r}: TLS settings need an mqtts:// URL')
        if parts.scheme == 'mqtts' and tls is None:
            tls = Tls()
        return cls(
            host=parts.hostname,
            port=port,
            username=unquote(parts.username or ''),
            password=unquote(parts.password or ''),
            tls=tls,
        )

    def with_password_file(self, path: Path, log: logging.Logger) -> 'Broker':
        """This broker with the password the file at `path` holds (its text, trimmed); a
        warning on `log` when users other than its owner may read the file."""
        try:
            password = path.read_text().strip()
        except OSError as error:
            raise SettingsError(f'cannot read the password file: {error}') from None
        if warning := exposure_warning(path):
            log.warning(f'--password-file {warning}')
        return replace(self, password=password)

    @property
    def url(self) -> str:
        """The URL without the password."""
        scheme = 'mqtts' if self.tls else 'mqtt'
        user = f'{self.username}@' if self.username else ''
        return f'{scheme}://{user}{self.host}:{self.port}'


@dataclass(frozen=True)
class BridgeSettings:
    robot_id: str
    broker: Broker = field(default_factory=Broker)
    prefix: str = DEFAULT_PREFIX
    source: str = 'CLOUD'
    """The source of the tasks the cloud starts without naming one."""
    state_file: Path | None = None
    """Where the last sequence number the broker acknowledged is kept; None: the default."""
    max_payload_bytes: int = DEFAULT_MAX_PAYLOAD_BYTES
    """The largest request accepted, and message sent (see outgoing.py); set the broker's
    message size limit to it, so that the broker refuses a larger request itself."""
    keepalive_sec: int = 10
    """How soon the broker notices a vanished bridge (and sends its last will): 1.5x this."""
    reconnect_max_sec: int = 2
    """The longest wait between two connection attempts (they start 1 s apart, doubling):
    how soon after a broker's return the results waiting are sent. Raise it for a fleet of
    thousands of robots on one broker, so that a broker restart is not met by all at once."""
    nice: int = GATEWAY_NICENESS
    """The bridge's nice value (task_manager.cpu_priority): 0 keeps the priority it was started
    with."""

    def __post_init__(self) -> None:
        check_name('robot_id', self.robot_id)
        if not self.prefix or self.prefix.startswith('/') or self.prefix.endswith('/'):
            raise SettingsError(f'prefix {self.prefix!r}: a topic prefix without leading or '
                                'trailing "/"')  # fmt: skip
        if any(c in self.prefix for c in '+#'):
            raise SettingsError(f'prefix {self.prefix!r} may not hold "+" or "#"')
        if not is_niceness(self.nice):
            raise SettingsError(f'nice {self.nice!r}: a whole number from 0 to {MAX_NICENESS}')

    @property
    def acked_file(self) -> Path:
        if self.state_file is not None:
            return self.state_file
        ros_home = Path(os.environ.get('ROS_HOME') or Path.home() / '.ros')
        return ros_home / 'task_manager' / 'mqtt' / f'{self.robot_id}.acked'


def check_name(what: str, name: str) -> None:
    """A robot id is one topic level: not empty, no '/', '+' or '#'."""
    if not name or any(c in name for c in TOPIC_FORBIDDEN):
        raise SettingsError(f'{what} {name!r}: one topic level, without "/", "+" or "#"')


def read_yaml(path: Path) -> dict[str, Any]:
    """The settings file: a mapping of the command line's long options (with _ for -)."""
    try:
        loaded = yaml.safe_load(path.read_text())
    except (OSError, yaml.YAMLError) as error:
        raise SettingsError(f'cannot read the settings file {path}: {error}') from None
    if loaded is None:
        return {}
    if not isinstance(loaded, dict):
        raise SettingsError(f'the settings file {path} must hold a mapping')
    return loaded


def tls_from(values: dict[str, Any]) -> Tls | None:
    """A Tls of the `tls` mapping of a settings file (None when absent)."""
    given = values.get('tls')
    if given is None or given is False:
        return None
    if given is True:
        return Tls()
    if not isinstance(given, dict):
        raise SettingsError('tls: a mapping of ca_file, cert_file, key_file, insecure')
    known = {f.name for f in fields(Tls)}
    unknown = sorted(set(given) - known)
    if unknown:
        raise SettingsError(f'tls: unknown keys {unknown}; allowed: {sorted(known)}')
    return Tls(**given)
