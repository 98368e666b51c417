"""`python -m bench` from the repository root (what `make bench` runs)."""

import os
import sys

from bench.harness import config

# Before rclpy loads: a domain of the bench's own, discovery kept on this machine.
os.environ['ROS_DOMAIN_ID'] = os.environ.get('BENCH_ROS_DOMAIN_ID', config.DEFAULT_DOMAIN_ID)
os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'

from bench.run import main

sys.exit(main())
