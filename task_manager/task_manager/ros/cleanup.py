"""Orderly teardown of rclpy entities that destroy_node leaves behind."""

from rclpy.node import Node


def destroy_waitables(node: Node) -> None:
    """Destroy the node's action servers and clients (waitables).

    rclpy's destroy_node leaves them to the garbage collector, which may run after the
    node is gone and crash the process.
    """
    for waitable in list(node.waitables):
        waitable.destroy()
