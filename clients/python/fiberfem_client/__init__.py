"""Python client of fiberfem services on DDS (docs/python-client.md)."""

from .client import Ack, Client, FiberfemError, State, Topology  # noqa: F401
