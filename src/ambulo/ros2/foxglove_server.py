"""The bridge's topics on a Foxglove WebSocket server (``foxglove-sdk``), to watch the robot live in
Foxglove or Lichtblick in a browser: the same CDR bytes as on ROS 2, with ``ros2msg`` schemas
(message definitions from ``rosbags``), and the simulated time broadcast as the server's clock."""

from __future__ import annotations

from .raw_types import typestore


class FoxgloveServer:
    """``log(topic, type, cdr, stamp_ns)`` to every connected Foxglove client."""

    def __init__(self, port: int = 8765, host: str = "127.0.0.1"):
        import foxglove

        self._foxglove = foxglove
        self.context = foxglove.Context()
        self.server = foxglove.start_server(name="ambulo", host=host, port=port, context=self.context,
                                            capabilities=[foxglove.Capability.Time])
        self.port = self.server.port
        self._channels: dict[str, object] = {}

    def log(self, topic: str, typename: str, data: bytes, stamp_ns: int) -> None:
        channel = self._channels.get(topic)
        if channel is None:
            msgdef, _ = typestore().generate_msgdef(typename, ros_version=2)
            schema = self._foxglove.Schema(name=typename, encoding="ros2msg", data=msgdef.encode())
            channel = self._foxglove.Channel(topic, schema=schema, message_encoding="cdr", context=self.context)
            self._channels[topic] = channel
        channel.log(data, log_time=stamp_ns)

    def broadcast_time(self, stamp_ns: int) -> None:
        self.server.broadcast_time(stamp_ns)

    def close(self) -> None:
        self.server.stop()


__all__ = ["FoxgloveServer"]
