"""A TCP port for a test's server (tests/ is on pytest's pythonpath: ``from ports import free_port``)."""

import socket


def free_port() -> int:
    """A port nothing listens on at 127.0.0.1 now (the OS picks it; a server started right after binds it)."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]
