"""Deciding what runs: resources, priorities, the queue, timeouts and retries (no rclpy).

`options` is what a request and a declaration may ask for, `claims` the resources a task
holds, `arbiter` the decision (start, pre-empt, queue or refuse) and the queue, `retry` the
backoff of a declaration's retries, `deadlines` every timeout on one clock, and `decisions`
the words each decision is explained in.
"""
