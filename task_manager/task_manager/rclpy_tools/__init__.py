"""rclpy helpers that the node, the client and the gateways share: the QoS of the wire, bounded
waits on futures, orderly teardown, and a client of an action's own services."""
