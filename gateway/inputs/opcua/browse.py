"""``stiction-gateway browse``: the variables under an OPC UA node, so that an engineer can
pick the node ids of a loop's OP and PV.

From the start node (default: the Objects folder) the hierarchical references are followed
through objects and folders, ``depth`` levels down; below the Objects folder the standard
``Server`` object (namespace 0) is left out unless it is the start node. For each variable:
its node id, data type, current value (or its status) and browse path. Failures are
:class:`~gateway.errors.DeviceError` naming the endpoint (or the configured device) and
the node, e.g. ``BadNodeIdUnknown`` for a start node the server does not have.
"""

from __future__ import annotations

import asyncio
import dataclasses
from typing import Any

from asyncua import ua
from asyncua.client.client import Client
from asyncua.ua.attribute_ids import AttributeIds
from asyncua.ua.object_ids import ObjectIdNames
from asyncua.ua.uaerrors import UaStatusCodeError

from ...errors import DeviceError
from .config import OpcUaDeviceConfig, parse_node_id
from .errors import map_error, status_name
from .session import discard, new_client, secure

__all__ = ["BrowsedVariable", "browse", "format_browse"]

OBJECTS = "i=85"


@dataclasses.dataclass(frozen=True)
class BrowsedVariable:
    node: str  # the node id to put in a loop's op/pv `node`
    data_type: str
    value: str  # the current value, or the status when it is not Good
    path: str  # browse names from the start node, "/"-separated


async def browse(cfg: OpcUaDeviceConfig, start: str | None = None, *, depth: int = 5,
                 limit: int = 10_000) -> list[BrowsedVariable]:
    """The variables under ``start`` (a node id string; default the Objects folder) on the
    server of ``cfg``, at most ``limit``; DeviceError on failure."""
    root = parse_node_id(start or OBJECTS)
    client = new_client(cfg)
    doing = "connecting"
    try:
        async with asyncio.timeout(4 * cfg.timeout_s + 1.0):
            if cfg.security is not None:
                await secure(client, cfg, cfg.security)
            await client.connect()
        doing = f"browsing node {root}"
        found = await _walk(client, ua.NodeId.from_string(root), depth, limit,
                            skip_ns0=start is None)
        doing = "reading the variables' data types and values"
        return await _describe(client, found)
    except Exception as exc:
        raise _error(exc, cfg, doing) from None
    finally:
        await discard(client, cfg.timeout_s)


def _error(exc: BaseException, cfg: OpcUaDeviceConfig, doing: str) -> DeviceError:
    name = cfg.name or cfg.endpoint
    if isinstance(exc, UaStatusCodeError) and doing.startswith("browsing"):
        return DeviceError(name, "exception", f"{doing}: {status_name(exc.code)}")
    return map_error(exc, device=name, endpoint=cfg.endpoint, doing=doing,
                     security=cfg.security, nodes=0)


async def _walk(client: Client, root: ua.NodeId, depth: int, limit: int, *, skip_ns0: bool
                ) -> list[tuple[ua.NodeId, str]]:
    """(node id, browse path) of the variables under ``root``, breadth first."""
    node = client.get_node(root)
    await node.read_browse_name()  # BadNodeIdUnknown for a node the server does not have
    level: list[tuple[Any, str]] = [(node, "")]
    seen = {root}
    found: list[tuple[ua.NodeId, str]] = []
    for _ in range(depth):
        children = await asyncio.gather(*(n.get_children_descriptions() for n, _ in level))
        nxt: list[tuple[Any, str]] = []
        for (_parent, path), refs in zip(level, children, strict=True):
            for ref in refs:
                nid = ref.NodeId
                if nid in seen or (skip_ns0 and nid.NamespaceIndex == 0):
                    continue
                seen.add(nid)
                child = f"{path}/{ref.BrowseName.Name}" if path else str(ref.BrowseName.Name)
                if ref.NodeClass == ua.NodeClass.Variable:
                    found.append((nid, child))
                    if len(found) >= limit:
                        return found
                elif ref.NodeClass == ua.NodeClass.Object:
                    nxt.append((client.get_node(nid), child))
        if not nxt:
            break
        level = nxt
    return found


async def _describe(client: Client, found: list[tuple[ua.NodeId, str]]
                    ) -> list[BrowsedVariable]:
    nodes = [client.get_node(nid) for nid, _ in found]
    if not nodes:
        return []
    types = await client.read_attributes(nodes, AttributeIds.DataType)
    values = await client.read_attributes(nodes)
    out = []
    for (nid, path), t, v in zip(found, types, values, strict=True):
        out.append(BrowsedVariable(nid.to_string(), _type_name(t), _value_text(v), path))
    return out


def _type_name(dv: ua.DataValue) -> str:
    tid = dv.Value.Value if dv.Value is not None else None
    if not isinstance(tid, ua.NodeId):
        return "?"
    if tid.NamespaceIndex == 0 and isinstance(tid.Identifier, int):
        return str(ObjectIdNames.get(tid.Identifier, tid.to_string()))
    return str(tid.to_string())


def _value_text(dv: ua.DataValue) -> str:
    code = dv.StatusCode.value if dv.StatusCode is not None else 0
    if code & 0xC0000000:
        return status_name(code)
    value = dv.Value.Value if dv.Value is not None else None
    text = f"{value:.7g}" if isinstance(value, float) else repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


def format_browse(variables: list[BrowsedVariable]) -> str:
    cells = [["node", "type", "value", "path"],
             *([v.node, v.data_type, v.value, v.path] for v in variables)]
    widths = [max(len(c[i]) for c in cells) for i in range(3)]
    return "".join("  ".join([*(c.ljust(w) for c, w in zip(row, widths, strict=False)),
                              row[3]]).rstrip() + "\n" for row in cells)
