"""A local mosquitto for VDA 5050 (tests and `make vda5050`): the MQTT bridge's broker
(accounts, persistence, the user name as client id) with the standard's topics in its ACL.

A vehicle's account (its serial number) reads its order and instantActions and writes its
state, connection, factsheet and visualization; a master's account writes the former and
reads the latter, of every vehicle of the interface.
"""

from collections.abc import Sequence
from pathlib import Path

from task_manager_mqtt.broker import MosquittoBroker
from task_manager_mqtt.settings import DEFAULT_MAX_PAYLOAD_BYTES

from task_manager_vda5050.topics import DEFAULT_INTERFACE, INBOUND, OUTBOUND, Vehicle

MASTER_USER = 'master'


class VdaBroker(MosquittoBroker):
    def __init__(
        self,
        folder: Path,
        manufacturer: str,
        serial_numbers: Sequence[str],
        masters: Sequence[str] = (MASTER_USER,),
        interface_name: str = DEFAULT_INTERFACE,
        port: int = 0,
        max_payload_bytes: int = DEFAULT_MAX_PAYLOAD_BYTES,
    ) -> None:
        """`max_payload_bytes`: the largest message it passes on (a client sending a larger
        one is disconnected)."""
        self.manufacturer = manufacturer
        self.interface_name = interface_name
        super().__init__(
            folder,
            robots=serial_numbers,
            port=port,
            clouds=masters,
            max_payload_bytes=max_payload_bytes,
        )

    def vehicle(self, serial_number: str) -> Vehicle:
        return Vehicle(self.manufacturer, serial_number, self.interface_name)

    def acl(self) -> str:
        any_vehicle = f'{self.interface_name}/v2/+/+'
        lines = ['# masters: write orders and instant actions, read what vehicles send']
        for user in self.clouds:
            lines += [f'user {user}']
            lines += [f'topic read {any_vehicle}/{name}' for name in OUTBOUND]
            lines += [f'topic write {any_vehicle}/{name}' for name in INBOUND]
            lines += ['']
        lines += ['# a vehicle (user name = serial number): its own topics only']
        for serial_number in self.robots:
            own = self.vehicle(serial_number)
            lines += [f'user {serial_number}']
            lines += [f'topic read {own.topic(name)}' for name in INBOUND]
            lines += [f'topic write {own.topic(name)}' for name in OUTBOUND]
            lines += ['']
        return '\n'.join(lines)
