"""Orderly teardown of rclpy entities that destroy_node leaves behind."""

from typing import Protocol, runtime_checkable

from rclpy.node import Node


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
