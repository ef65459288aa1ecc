"""The contract out: JSON Schemas of every message, and the docs' message table."""

from __future__ import annotations

from typing import Annotated, Any, get_args, get_origin

from pydantic import TypeAdapter

from .base import ErrorReply
from .endpoints import SERVICES, TOPICS


def _schema_of(model: Any) -> dict:
    return TypeAdapter(model).json_schema()


def json_schemas() -> dict[str, dict]:
    """Return every message's JSON Schema, keyed by file stem (``topic.rr.result``, ``service.wm_manager.sync``)."""
    out: dict[str, dict] = {}
    for topic in TOPICS:
        out["topic." + topic.name.replace("/", ".")] = _schema_of(topic.schema)
    for service in SERVICES:
        stem = "service." + service.name.replace("/", ".").replace("<domain>", "DOMAIN")
        out[stem + ".request"] = _schema_of(service.request)
        out[stem + ".reply"] = _schema_of(service.reply)
    out["service.error_reply"] = _schema_of(ErrorReply)
    return out


def fields_of(schema: Any) -> list[str]:
    """Return the field names a schema (model or union of models) names, in order, without duplicates."""
    if get_origin(schema) is Annotated:  # e.g. a discriminated union
        schema = get_args(schema)[0]
    models = getattr(schema, "__args__", None) or (schema,)
    names: list[str] = []
    for model in models:
        for name in getattr(model, "model_fields", {}):
            if name not in names:
                names.append(name)
    return names


def message_table() -> list[str]:
    """Return the rows of the docs' message table: ``| name | from -> to | QoS | fields |``."""
    rows = []
    for topic in TOPICS:
        qos = topic.qos.describe() + (f" (readers {topic.reader_qos.depth})" if topic.reader_qos else "")
        fields = ", ".join(f"`{f}`" for f in fields_of(topic.schema))
        rows.append(f"| `{topic.name}` | {topic.publishers} -> {topic.subscribers} | {qos} | {fields} |")
    for service in SERVICES:
        request = ", ".join(f"`{f}`" for f in fields_of(service.request)) or "(none)"
        reply = ", ".join(f"`{f}`" for f in fields_of(service.reply)) or "(by op)"
        rows.append(f"| `{service.name}` | {service.clients} -> {service.server} | service | {request} -> {reply} |")
    return rows
