"""What the benchmarks run: task names, topics, sample sizes and the node's parameters file."""

from pathlib import Path
from typing import Any

from task_manager.testing.process import action_task, service_task, write_params_file

# Tests pick their ROS domain in 1..100 (conftest.py); the bench stays apart from them.
DEFAULT_DOMAIN_ID = '101'

FIBONACCI_TOPIC = '/bench/fibonacci'
TRIGGER_TOPIC = '/bench/trigger'
HOLD_TOPIC = '/bench/hold'
SLOW_SERVICE_TOPIC = '/bench/slow_service'
MISSING_TOPIC = '/bench/missing_server'
RELEASE_GOALS_TOPIC = '/bench/release_goals'
RELEASE_CALLS_TOPIC = '/bench/release_calls'
FEEDBACK_TOPIC = '/bench/feedback'
RELEASE_FEEDBACK_TOPIC = '/bench/release_feedback'

# The direct baselines go to twins of the servers (same process, same code) under names of
# their own: every client of a service takes every response its server sends, its own or not
# (rmw_fastrtps filters them in the take), so a baseline sent to the node's servers would
# wake the idle node for each reply, and the node's requests would wake the bench's client.
DIRECT_FIBONACCI_TOPIC = '/bench/direct/fibonacci'
DIRECT_TRIGGER_TOPIC = '/bench/direct/trigger'
DIRECT_HOLD_TOPIC = '/bench/direct/hold'
# the throughput benchmark's floor (bench/harness/relay.py): its ExecuteTask, and its own twin of
# the instant Fibonacci server
RELAY_ACTION = '/bench/relay/execute_task'
RELAY_FIBONACCI_TOPIC = '/bench/relay/fibonacci'

FIBONACCI_TASK = 'bench/fibonacci'
TRIGGER_TASK = 'bench/trigger'
HOLD_TASK = 'bench/hold'
SLOW_SERVICE_TASK = 'bench/slow_service'
MISSING_TASK = 'bench/missing_server'
FEEDBACK_TASK = 'bench/feedback'
MISSION_TASK = 'system/mission'

FIBONACCI_DATA = '{"order": 0}'
TRIGGER_DATA = '{}'

SERVER_WAIT_TIMEOUT_SEC = 5.0
SLOW_CANCEL_TIMEOUT_SEC = 3.0

WARM_UP_SAMPLES = 30
DISPATCH_SAMPLES = 300
THROUGHPUT_TASKS = 500
THROUGHPUT_ROUNDS = 3
CONCURRENT_TASKS = 1000
LOADED_SAMPLES = 20
# concurrency: more instant tasks, up to MAX_LOADED_SAMPLES, until this many publications
MIN_PUBLICATION_GAPS = 5
MAX_LOADED_SAMPLES = 400
# the node's CPU while the CONCURRENT_TASKS wait on their server
WAITING_CPU_SEC = 5.0
# the leak check: the node's RSS while this many instant tasks run, in bursts (30,000 take
# ~110 s; runs of 100,000 showed the RSS steady from the first sample on; 50,000 until
# 2026-11-29, cut for issue 40's 20 minutes of `make bench`)
LEAK_TASKS = 30_000
LEAK_BURST = 500
LEAK_SAMPLE_EVERY = 3_000
# memory: the node's and the web gateway's RSS after this many tasks through the gateway
MEMORY_TASKS = 10_000
MEMORY_WARM_UP = 500
MEMORY_CLIENTS = 8
MEMORY_GROWTH_TARGET_PERCENT = 20.0
PUBLICATION_SAMPLES = 20
ISOLATION_SAMPLES = 40
MISSION_SUBTASKS = 200
MISSION_ROUNDS = 3

# The cost of a node setting (the event stream, the history file): the node restarted
# without (False) or with (True) it, in this order (ABBA, so that a drift in the machine's
# load hits both alike); in each phase, the dispatch samples (per kind) and the bursts of
# the throughput benchmark.
SETTING_PHASES = (False, True, True, False)
SETTING_DISPATCH_SAMPLES = 150
SETTING_BURSTS = 2

# A server publishing feedback at FEEDBACK_RATE_HZ (an rclpy timer) for one task, while
# instant tasks run; quiet and busy blocks alternate (ABBA) over FEEDBACK_ROUNDS rounds.
FEEDBACK_RATE_HZ = 100.0
FEEDBACK_ROUNDS = 4
FEEDBACK_BLOCK_SAMPLES = 50
# the web gateway: round trips through it vs ExecuteTask; event streams open at once
WEB_SAMPLES = 150
WEB_STREAMS = 200
WEB_STREAM_TASKS = 50
# the MQTT bridge: round trips from the cloud client vs ExecuteTask; results of an outage
MQTT_SAMPLES = 150
MQTT_OUTAGE_TASKS = 1000
# the node's start-up (restarts) and its CPU when idle
STARTUP_SAMPLES = 5
IDLE_SEC = 10.0

# The node's ExecuteTask server keeps each finished goal 10 s, as rclpy's servers do (the
# bench's hold and feedback servers walk all they keep on each event): each benchmark, the
# held ramps and the measurements of memory and idle CPU start once they are gone
# (ctx.wait_kept_goals_gone); a full bench with 2 s pauses there measured the node's CPU while
# 1,000 tasks wait at 25.6 % (1.4-3.2 % alone) and lost the attached ramps.
KEPT_GOALS_SEC = 10.5
# A pause between timed measurements (ctx.settle). It was KEPT_GOALS_SEC, for rclpy's
# ActionServer, which walks every goal it keeps on each event; the node's ExecuteTask server
# (ros/serving/action_services_server.py) and the bench's instant server
# (harness/lean_action.py) do not: the burst's share of direct was 41-43 % with either pause
# (2026-11-27, ABBA, `--only throughput`), and the whole bench ~10 minutes shorter.
SETTLE_SEC = 2.0

# Bounds on every wait, so that a broken node fails the bench instead of hanging it.
SAMPLE_TIMEOUT_SEC = 10.0
BURST_TIMEOUT_SEC = 120.0
CONNECT_TIMEOUT_SEC = 20.0


def node_parameters(**overrides: Any) -> dict[str, Any]:
    """The node's parameters: instant, held, slow, feedback and missing servers.

    All tasks are reentrant but the slow service's; `overrides` sets node-level parameters
    (e.g. publish_task_events).
    """
    entries = {
        'fibonacci': action_task(FIBONACCI_TASK, FIBONACCI_TOPIC, reentrant=True),
        'feedback': action_task(FEEDBACK_TASK, FEEDBACK_TOPIC, reentrant=True),
        'trigger': service_task(
            TRIGGER_TASK, TRIGGER_TOPIC, 'std_srvs/srv/Trigger', reentrant=True
        ),
        'hold': action_task(HOLD_TASK, HOLD_TOPIC, reentrant=True),
        'missing': action_task(MISSING_TASK, MISSING_TOPIC, reentrant=True),
        'slow_service': service_task(
            SLOW_SERVICE_TASK,
            SLOW_SERVICE_TOPIC,
            'std_srvs/srv/Trigger',
            cancel_timeout=SLOW_CANCEL_TIMEOUT_SEC,
        ),
    }
    return {
        'tasks': list(entries),
        'server_wait_timeout': SERVER_WAIT_TIMEOUT_SEC,
        **overrides,
        **entries,
    }


def write_node_params(directory: Path, name: str = 'bench_params', **overrides: Any) -> Path:
    """The parameters file `name`.yaml; the node's task history (a file, as by default) is new
    and in `directory`, so that every node starts with an empty one."""
    overrides.setdefault('history_path', str(directory / f'{name}_history.sqlite'))
    return write_params_file(directory / f'{name}.yaml', node_parameters(**overrides))
