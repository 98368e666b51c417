"""Who started a task, as its source says: a door's own source (`WEB`, `CLOUD`), followed by the
name of who asked through it (`WEB:alice`, `CLOUD:alice`).

Plain Python, so that a door without rclpy (the fleet console) names its callers as the
gateways do.
"""

import re

from task_manager.core.admission.priority import SOURCE_SEPARATOR

SOURCE_NAME = re.compile(r'[A-Za-z0-9._@-]{1,64}')
"""A name a door puts after its own source (a web token's, an MQTT request's): no separator in
it, so that no name can make another door's source."""
SOURCE_NAME_RULE = "1 to 64 letters, digits, '.', '_', '@' or '-'"


def door_source(door: str, name: str = '') -> str:
    """The source of what `name` starts through the door whose source is `door`: `door`, or
    `door:name` (`WEB:alice`)."""
    return f'{door}{SOURCE_SEPARATOR}{name}' if name else door
