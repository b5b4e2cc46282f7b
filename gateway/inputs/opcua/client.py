"""OPC UA source: one asyncua client (one session) per device.

Every read asks for the Value attribute of all of the device's nodes in one Read service call
(``Client.read_attributes``; several only when ``max_nodes_per_read`` asks for it) and keeps
each value's StatusCode (:mod:`.values` says what each becomes). A failure of the whole
device (refused, timed out, session lost) raises :class:`~gateway.errors.DeviceError`
(:mod:`.errors`); no asyncua exception leaves this module.

The source does not reconnect by itself and asyncua's auto-reconnect is off: when the
session is lost, ``read`` raises and the poller closes the source and calls ``connect``
again on its own backoff, logging the outage once.
"""

from __future__ import annotations

import asyncio
import logging
import time
from collections.abc import Sequence
from typing import Any

from asyncua import ua
from asyncua.client.client import Client
from asyncua.client.ua_client import UaClientState

from ...core.points import PointSpec, Quality
from ...errors import DeviceError
from ..base import ReadResult
from .config import OpcUaDeviceConfig, OpcUaPoint
from .errors import map_error, status_name
from .session import discard, new_client, secure
from .values import StatusLog, convert, refused

__all__ = ["OpcUaInput"]

_log = logging.getLogger("gateway.inputs.opcua")


def _node_text(address: Any) -> str:
    if isinstance(address, OpcUaPoint):
        return address.node
    if isinstance(address, str):
        return address
    raise TypeError(f"an OPC UA point address must be an OpcUaPoint or a node id string, "
                    f"was {address!r}")


class OpcUaInput:
    """:class:`~gateway.inputs.base.Source` for one OPC UA server."""

    def __init__(self, config: OpcUaDeviceConfig, points: Sequence[PointSpec]) -> None:
        self.config = config
        self.name = config.name
        self.points = tuple(points)
        self._node_ids = [ua.NodeId.from_string(_node_text(p.address)) for p in self.points]
        self._client: Client | None = None
        self._read_index: list[int] = []  # point indexes read, in request order
        self._chunks: list[list[Any]] = []  # asyncua Node objects per Read call
        self._status = StatusLog(self.name, self.points, self._node_ids)
        self._last_status = self._status.status  # of the last read (probe shows it)

    async def __aenter__(self) -> OpcUaInput:
        """``async with OpcUaInput(...) as source``: connected inside, closed after."""
        await self.connect()
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.close()

    @property
    def connected(self) -> bool:
        c = self._client
        return c is not None and c.uaclient.state is UaClientState.CONNECTED

    async def connect(self) -> None:
        """Open a session (dropping any old one); DeviceError on failure."""
        await self._drop()
        try:
            async with asyncio.timeout(4 * self.config.timeout_s + 1.0):
                self._client = await self._open()
        except Exception as exc:
            raise self._error(exc, "connecting") from None

    async def read(self) -> ReadResult:
        """Read every point once; DeviceError if the device fails (then ``connect`` again)."""
        client = self._client
        if client is None or not self.connected:
            await self._drop()
            raise DeviceError(self.name, "connect", "not connected (session lost)")
        t = time.time()
        results: list[ua.DataValue] = []
        try:
            async with asyncio.timeout(self.config.timeout_s * max(1, len(self._chunks)) + 0.5):
                for chunk in self._chunks:
                    results.extend(await client.read_attributes(chunk))
        except Exception as exc:
            failure = self._error(exc, "reading")
            await self._drop()
            raise failure from None
        if len(results) != len(self._read_index):
            await self._drop()
            raise DeviceError(self.name, "protocol", f"the server answered {len(results)} "
                              f"values for {len(self._read_index)} nodes")
        values, quality, status = convert(results, self._read_index, len(self.points))
        self._last_status = status
        err = refused(status, self.points, self._node_ids, device=self.name,
                      endpoint=self.config.endpoint)
        if err is not None:  # serves nothing: one device error, not a line per point
            quality[:] = Quality.NO_COMM
            return ReadResult(t=t, values=values, quality=quality,
                              requests=len(self._chunks), errors=(err,))
        self._status.update(status)
        return ReadResult(t=t, values=values, quality=quality, requests=len(self._chunks))

    def point_status(self) -> list[str]:
        """Per point, the StatusCode of its last read when not Good ('' when Good)."""
        return [status_name(int(c)) if int(c) & 0xC0000000 else ""
                for c in self._last_status]

    async def close(self) -> None:
        """Close the session; never raises."""
        await self._drop()

    # ------------------------------------------------------------------ internals

    async def _open(self) -> Client:
        client = new_client(self.config)
        try:
            if self.config.security is not None:
                await secure(client, self.config, self.config.security)
            await client.connect()
            await self._prepare_nodes(client)
        except BaseException:
            await discard(client, self.config.timeout_s)
            raise
        return client

    async def _prepare_nodes(self, client: Client) -> None:
        """Resolve ``nsu=`` node ids against the server's namespace array and build the
        Read requests; points whose node cannot be resolved are left out (BAD)."""
        ids: list[ua.NodeId | None] = list(self._node_ids)
        uris = {n.NamespaceUri for n in self._node_ids
                if isinstance(n, ua.ExpandedNodeId) and n.NamespaceUri}
        if uris:
            namespaces = list(await client.get_namespace_array())
            for i, n in enumerate(self._node_ids):
                if isinstance(n, ua.ExpandedNodeId) and n.NamespaceUri:
                    if n.NamespaceUri in namespaces:
                        ids[i] = ua.NodeId(n.Identifier, ua.Int16(namespaces.index(n.NamespaceUri)),
                                           n.NodeIdType)
                    else:
                        ids[i] = None
                        _log.warning("OPC UA device %s: %s %s: the server has no namespace %s",
                                     self.name, self.points[i].loop, self.points[i].role,
                                     n.NamespaceUri)
        self._read_index = [i for i, n in enumerate(ids) if n is not None]
        nodes = [client.get_node(n) for n in ids if n is not None]
        size = self.config.max_nodes_per_read or max(1, len(nodes))
        self._chunks = [nodes[k:k + size] for k in range(0, len(nodes), size)]

    def _error(self, exc: BaseException, doing: str) -> DeviceError:
        return map_error(exc, device=self.name, endpoint=self.config.endpoint, doing=doing,
                         security=self.config.security, nodes=len(self._read_index))

    async def _drop(self) -> None:
        client, self._client = self._client, None
        self._chunks = []
        self._read_index = []
        if client is not None:
            await discard(client, self.config.timeout_s)
