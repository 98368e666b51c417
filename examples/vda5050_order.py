"""Send a VDA 5050 order to the demo robot, as a master control would, and print its progress
(run `make vda5050` first; it prints this command with the broker URL).

.venv/bin/python examples/vda5050_order.py --broker-url mqtt://master:PASSWORD@127.0.0.1:PORT

The order: from the origin to a shelf, a photo there (a HARD action: the robot stands still
while it is taken), and back. It prints each state that changes the order's progress.
"""

import argparse
import itertools
import json
import queue
import sys
import uuid
from datetime import UTC, datetime
from typing import Any

import paho.mqtt.client as mqtt
from paho.mqtt.enums import CallbackAPIVersion
from task_manager_mqtt.settings import Broker

VEHICLE = 'uagv/v2/demo/robot1'
TIMEOUT_SEC = 120.0


def node(node_id: str, sequence_id: int, x: float, y: float, *actions: Any) -> dict[str, Any]:
    position = {'x': x, 'y': y, 'mapId': 'demo'}
    return {'nodeId': node_id, 'sequenceId': sequence_id, 'released': True,
            'nodePosition': position, 'actions': list(actions)}  # fmt: skip


def the_order(order_id: str) -> dict[str, Any]:
    photo = {'actionId': f'photo-{order_id}', 'actionType': 'take_photo', 'blockingType': 'HARD',
             'actionParameters': [{'key': 'camera', 'value': 'front'}]}  # fmt: skip
    nodes = [
        node('home', 0, 0.0, 0.0),
        node('shelf', 2, 2.0, 1.0, photo),
        node('back', 4, 0.0, 0.0),
    ]
    edges = [
        {'edgeId': f'e{a["sequenceId"] + 1}', 'sequenceId': a['sequenceId'] + 1, 'released': True,
         'startNodeId': a['nodeId'], 'endNodeId': b['nodeId'], 'actions': []}
        for a, b in itertools.pairwise(nodes)
    ]  # fmt: skip
    return {
        'headerId': 0,
        'timestamp': datetime.now(UTC).isoformat(timespec='milliseconds').replace('+00:00', 'Z'),
        'version': '2.0.0',
        'manufacturer': 'demo',
        'serialNumber': 'robot1',
        'orderId': order_id,
        'orderUpdateId': 0,
        'nodes': nodes,
        'edges': edges,
    }


def progress(state: dict[str, Any]) -> str:
    actions = ', '.join(f'{a["actionType"]} {a["actionStatus"]}' for a in state['actionStates'])
    return (f'last node {state["lastNodeId"] or "-":6} driving {state["driving"]!s:5} '
            f'nodes left {len(state["nodeStates"])}  actions: {actions or "-"}')  # fmt: skip


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument('--broker-url', required=True, help='mqtt://master:PASSWORD@HOST:PORT')
    broker = Broker.from_url(parser.parse_args().broker_url)
    states: queue.SimpleQueue[dict[str, Any]] = queue.SimpleQueue()
    client = mqtt.Client(CallbackAPIVersion.VERSION2, client_id=broker.username)
    client.username_pw_set(broker.username, broker.password)
    client.on_message = lambda _, __, message: states.put(json.loads(message.payload))
    client.connect(broker.host, broker.port)
    client.subscribe(f'{VEHICLE}/state')
    client.loop_start()
    order_id = f'example-{uuid.uuid4().hex[:6]}'
    client.publish(f'{VEHICLE}/order', json.dumps(the_order(order_id)))
    print(f'order {order_id} sent to {VEHICLE}', flush=True)
    shown = ''
    try:
        while True:
            state = states.get(timeout=TIMEOUT_SEC)
            if state['orderId'] != order_id:
                continue
            line = progress(state)
            if line != shown:
                print(f'  {line}', flush=True)
                shown = line
            ended = all(a['actionStatus'] in ('FINISHED', 'FAILED') for a in state['actionStates'])
            if not state['nodeStates'] and ended:
                failed = state['errors'] or any(
                    a['actionStatus'] == 'FAILED' for a in state['actionStates']
                )
                print('order failed' if failed else 'order done', flush=True)
                return 1 if failed else 0
    except queue.Empty:
        print(f'no progress for {TIMEOUT_SEC:.0f} s', file=sys.stderr)
        return 1
    finally:
        client.loop_stop()
        client.disconnect()


if __name__ == '__main__':
    sys.exit(main())
