"""How the Task Manager's own processes configure Fast DDS discovery (no rclpy here).

Fast DDS announces a new participant 5 times in its first half second, then every 3 s. A
process that starts beside running ones (taskctl, the gateways, the node itself) was often
found only at that periodic announcement: measured here, a web gateway reached its node
after 2.8 s in half of 10 starts and 0.14 s in the others; taskctl took 0.8 or 2.3 s. With
20 announcements in the first second (fastdds_discovery.xml), most starts connected within
0.5 s, but still one in 8 to 16 after 2.3-3 s: the running process answers a newcomer's first
announcement once, and when that answer is missed the newcomer learns of it at its next
periodic announcement. Announcing each second bounds that wait to 1 s (16 gateway starts:
at most 1.14 s; 2.88 s with the 3 s period).

The profile also gives each of these processes a 5 s lease (Fast DDS's default: 20 s): one that
ends without a word (SIGKILL, a crash, a power loss) is forgotten by the others 5 s after they
last heard from it. While they remembered a dead client, a newcomer now and then never matched
some of the node's endpoints (a taskctl `get_parameters is not available`, after waiting 10 or
30 s): in 34 of 240 starts 10-30 s after ten clients were killed (shared memory and UDP, or UDP
alone); with the clients' lease at 5 s, in none of 240 (2 of 30 in a run beside a full test
run, so rarer, not gone: the cause is inside Fast DDS; with four taskctls at a time against one
node, about 1 in 100 still never matched an endpoint of the node, so taskctl tries a second
participant after half its timeout and a gateway's hearing check looks for a node it never
met). Any message from a participant renews its lease; a silent one announces itself 5 times
in it.

The profile also turns Fast DDS's type propagation off (XTypes' TypeLookup service, which
ROS 2 does not use: rmw_fastrtps matches types by name and hash). Its request thread answered
other participants' questions about this one's types, and a participant deleted while it did
crashed the process (a null mutex in `WriterHistory::create_change`, seen in core files): a
segmentation fault as a program ended soon after it started, a taskctl or a node refusing its
parameters, in 6 of 480 demo starts with a bad parameters file beside a starting robot and web
gateway; none of 300 with it off.

Call `use_quick_discovery()` before rclpy starts a participant; a profile file the user gives
Fast DDS (FASTDDS_DEFAULT_PROFILES_FILE) is left alone.
"""

import os
from collections.abc import MutableMapping
from pathlib import Path

PROFILE_FILE = Path(__file__).with_name('fastdds_discovery.xml')
PROFILE_VARIABLES = ('FASTDDS_DEFAULT_PROFILES_FILE', 'FASTRTPS_DEFAULT_PROFILES_FILE')
FAST_DDS_RMWS = ('', 'rmw_fastrtps_cpp', 'rmw_fastrtps_dynamic_cpp')


def use_quick_discovery(environ: MutableMapping[str, str] = os.environ) -> bool:
    """Point Fast DDS at fastdds_discovery.xml (inherited by child processes); whether it did.

    Nothing changes when another RMW is chosen or a profile file is already set.
    """
    if environ.get('RMW_IMPLEMENTATION', '') not in FAST_DDS_RMWS:
        return False
    if any(environ.get(variable) for variable in PROFILE_VARIABLES):
        return False
    environ['FASTDDS_DEFAULT_PROFILES_FILE'] = str(PROFILE_FILE)
    return True
