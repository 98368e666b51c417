"""Benchmarks of the gateways attached to a node: web, MQTT, VDA 5050."""
