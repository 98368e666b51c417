"""Orderly teardown of rclpy entities that destroy_node leaves behind."""

import weakref
from typing import Protocol, runtime_checkable

from rclpy.node import Node
from rclpy.timer import Timer


@runtime_checkable
class _Destroyable(Protocol):
    """What rclpy's action servers, action clients and event handlers have, and Waitable lacks."""

    def destroy(self) -> None: ...


def destroy_waitables(node: Node) -> None:
    """Destroy the node's action servers and clients (waitables).

    rclpy's destroy_node leaves them to the garbage collector, which may run after the
    node is gone and crash the process.
    """
    for waitable in list(node.waitables):
        if isinstance(waitable, _Destroyable):
            waitable.destroy()


def destroy_timer(node: Node, timer: Timer) -> None:
    """Destroy a timer of the node, leaving nothing of it behind.

    rclpy's destroy_timer leaves the timer's weak reference in its callback group's set of
    entities (rclpy 9): about 140 bytes for each timer ever made, which a node making timers
    per task grew by without bound (the bench's leak check).
    """
    node.destroy_timer(timer)
    if timer.callback_group is not None:
        timer.callback_group.entities.discard(weakref.ref(timer))
