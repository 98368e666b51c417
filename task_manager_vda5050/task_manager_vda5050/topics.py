"""The vehicle's topics and the header of every message it sends."""

import json
from dataclasses import dataclass, field
from datetime import UTC, datetime
from typing import Any

VERSION = '2.0.0'
MAJOR = 'v2'
DEFAULT_INTERFACE = 'uagv'
INBOUND = ('order', 'instantActions')
OUTBOUND = ('state', 'connection', 'factsheet', 'visualization')
# key: topic, value: (QoS, retained), as the standard asks
DELIVERY = {
    'order': (0, False),
    'instantActions': (0, False),
    'state': (0, False),
    'visualization': (0, False),
    'factsheet': (0, True),
    'connection': (1, True),
}
TOPIC_FORBIDDEN = ('+', '#', '/')


@dataclass(frozen=True)
class Vehicle:
    """Who the vehicle is on the broker."""

    manufacturer: str
    serial_number: str
    interface_name: str = DEFAULT_INTERFACE

    def __post_init__(self) -> None:
        for what in ('manufacturer', 'serial_number', 'interface_name'):
            value = getattr(self, what)
            if not value or any(c in value for c in TOPIC_FORBIDDEN):
                raise ValueError(f'{what} {value!r}: one topic level, without "/", "+" or "#"')

    @property
    def prefix(self) -> str:
        return f'{self.interface_name}/{MAJOR}/{self.manufacturer}/{self.serial_number}'

    def topic(self, name: str) -> str:
        return f'{self.prefix}/{name}'


def timestamp(moment: datetime | None = None) -> str:
    """ISO 8601 in UTC with milliseconds and a Z, e.g. 2024-04-15T11:40:03.120Z."""
    moment = moment or datetime.now(UTC)
    return moment.astimezone(UTC).isoformat(timespec='milliseconds').replace('+00:00', 'Z')


@dataclass
class Headers:
    """The header of each message sent: headerId counted per topic, from 0."""

    vehicle: Vehicle
    # key: topic, value: the next headerId
    _next: dict[str, int] = field(default_factory=dict)

    def header(self, topic: str) -> dict[str, Any]:
        header_id = self._next.get(topic, 0)
        self._next[topic] = header_id + 1
        return self._fields(header_id)

    def largest_size(self) -> int:
        """The most bytes a header takes in a message's JSON (a headerId of 20 digits)."""
        return len(json.dumps(self._fields(2**64)))

    def _fields(self, header_id: int) -> dict[str, Any]:
        return {
            'headerId': header_id,
            'timestamp': timestamp(),
            'version': VERSION,
            'manufacturer': self.vehicle.manufacturer,
            'serialNumber': self.vehicle.serial_number,
        }
