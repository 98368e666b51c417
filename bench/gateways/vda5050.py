"""The VDA 5050 adapter: an order of 10 nodes from a master control (a bare MQTT client here)
until the vehicle's state says it is done, vs the same 10 tasks one after the other through
ExecuteTask (interleaved, in one run); the time the adapter adds per node.

The nodes' drives are the bench's instant Fibonacci task (the mapping's navigation task), so
the order measures the adapter, the broker and the mission, not a robot. The broker is
Debian's mosquitto on loopback with the accounts and ACL of the tests; the adapter runs as
users run it (`task-manager-vda5050`, in the bench's ROS domain).
"""

import json
import time
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import yaml
from task_manager_mqtt.testing import RawClient
from task_manager_vda5050.broker import MASTER_USER
from task_manager_vda5050.testing import (
    MANUFACTURER,
    SERIAL,
    AdapterProcess,
    BrokerProcess,
    node,
    order,
)
from task_manager_vda5050.topics import timestamp

from bench.harness import config
from bench.harness.context import BenchContext
from bench.harness.replies import BenchError
from bench.harness.report import Row
from bench.harness.stats import Summary
from bench.node.dispatch import interleaved

NODES = 10
SAMPLES = 30
WARM_UP = 5


@contextmanager
def running_adapter(ctx: BenchContext) -> Iterator[tuple[RawClient, str]]:
    """The broker, the adapter on the bench's node, and a master's client that hears state."""
    mapping = ctx.log_dir / 'vda5050_mapping.yaml'
    navigation = {
        'task_name': config.FIBONACCI_TASK,
        'task_data': json.loads(config.FIBONACCI_DATA),
    }
    mapping.write_text(yaml.safe_dump({'navigation': navigation}))
    broker = BrokerProcess(ctx.log_dir / 'vda5050_broker', MANUFACTURER, [SERIAL], [MASTER_USER])
    broker.start()
    adapter = AdapterProcess(broker, mapping=mapping, nice=None)  # as users start it
    prefix = broker.vehicle(SERIAL).prefix
    try:
        password = broker.passwords[MASTER_USER]
        with RawClient(broker.port, MASTER_USER, password, topics=[f'{prefix}/state']) as master:
            yield master, prefix
    except TimeoutError as error:
        said = '\n'.join(adapter.log_lines[-10:])
        raise BenchError(f'{error}; the adapter said:\n{said}') from error
    finally:
        adapter.stop()
        broker.stop()


def order_ms(master: RawClient, prefix: str, number: int) -> float:
    """From publishing an order of NODES nodes until a state of it has no node left."""
    order_id = f'bench-{number}'
    nodes = [node(f'n{i}', 2 * i, float(i), 0.0) for i in range(NODES)]
    header = {'headerId': number, 'timestamp': timestamp(), 'version': '2.0.0',
              'manufacturer': MANUFACTURER, 'serialNumber': SERIAL}  # fmt: skip
    payload = json.dumps({**header, **order(order_id, *nodes)})
    seen = len(master.received)
    started = time.perf_counter()
    master.publish(f'{prefix}/order', payload, wait=False)

    def done(received: list[Any]) -> bool:
        for message in received[seen:]:
            state = json.loads(message.payload)
            if state['orderId'] == order_id and state['errors']:
                raise BenchError(f'vda5050 order: {state["errors"]}')
            if state['orderId'] == order_id and not state['nodeStates']:
                return True
        return False

    master.wait_for(done, f'order {order_id} done')
    return (time.perf_counter() - started) * 1000


def run(ctx: BenchContext) -> None:
    numbers = iter(range(1, 1_000_000))

    def direct_ms() -> float:
        return sum(ctx.fibonacci_task_ms() for _ in range(NODES))

    with running_adapter(ctx) as (master, prefix):
        interleaved(lambda: order_ms(master, prefix, next(numbers)), direct_ms, WARM_UP)
        ctx.settle()
        through_ms, alone_ms = interleaved(
            lambda: order_ms(master, prefix, next(numbers)), direct_ms, SAMPLES
        )
    through, alone = Summary.of(through_ms), Summary.of(alone_ms)
    per_node = (through.median - alone.median) / NODES
    ctx.report.add(
        Row(
            benchmark=f'vda5050 order of {NODES} nodes',
            metric=f'order -> state done, ms med / p95, n={through.count}',
            measured=through.text(),
            baseline=f'{alone.text()} {NODES} tasks through ExecuteTask',
            ratio=f'{per_node:+.2f} ms per node',
        )
    )
    ctx.report.note(
        f'vda5050: the order is one mission, whose subtasks the node runs one after the other '
        f'without a client round trip between them; the {NODES} ExecuteTask goals are sent one '
        'after the other by the bench client, each once the one before has its result'
    )
