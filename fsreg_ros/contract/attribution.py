"""Telling replies apart: request fingerprints and the answer cache's key.

RR and REG publish every answer on one topic that every requester hears, and a request
``id`` is the requester's choice, so two requesters may pick the same one.  Each answer
therefore echoes what identifies its request:

* ``client``: the request's own ``client`` field, if it gave one (a requester's name;
  give one and filter answers by it).  Ids are per client: the same id from two clients
  is two requests.
* ``request``: the request's fingerprint (:func:`fingerprint`).  A requester that gives
  no ``client`` compares it with the fingerprint of what it sent.

A request that reuses an id (of the same client) for a different request gets an error
of kind ``IdConflict`` whose ``conflicts_with`` names the request holding the id
(its ``client`` and fingerprint), never the other request's answer.
"""

from __future__ import annotations

import hashlib
import json
from typing import Any, Mapping, Optional

#: Hex digits of a fingerprint (64 bits: collisions between two live requests are negligible).
FINGERPRINT_HEX = 16


def fingerprint(request: Mapping[str, Any]) -> str:
    """Return the fingerprint of a request: SHA-256 of its canonical JSON, 16 hex digits.

    Canonical JSON is ``json.dumps(request, sort_keys=True, separators=(",", ":"),
    ensure_ascii=True)`` of the object as decoded, every field included; a requester
    gets the same text from the object it sent.
    """
    text = json.dumps(request, sort_keys=True, separators=(",", ":"), ensure_ascii=True)
    return hashlib.sha256(text.encode("ascii")).hexdigest()[:FINGERPRINT_HEX]


def cache_key(request: Mapping[str, Any]) -> tuple[Optional[str], str]:
    """Return what an id means within: ``(client, type:id)`` (ids are per client; ``1`` and ``"1"`` differ)."""
    client = request.get("client")
    rid = request["id"]
    return (client if isinstance(client, str) else None, f"{type(rid).__name__}:{rid}")


def reference_id(request: Mapping[str, Any], asker: str) -> str:
    """Return the id of the act of referring a REG request is: ``<asker>/<16 hex digits>`` of its (client, id).

    ``asker`` names the REG node's port (its ``client`` id at the consultant).  A resent
    request (same client, same id) gets the same reference id, so its ``open`` begins no
    second reference episode of the target (docs/semantics.md section 2).
    """
    text = json.dumps(cache_key(request), separators=(",", ":"), ensure_ascii=True)
    return f"{asker}/{hashlib.sha256(text.encode('ascii')).hexdigest()[:FINGERPRINT_HEX]}"


def attribution(request: Mapping[str, Any], fingerprint_text: Optional[str] = None) -> dict:
    """Return the fields an answer to ``request`` carries: ``id``, ``client`` (if given), ``request``."""
    out: dict[str, Any] = {"id": request["id"]}
    if isinstance(request.get("client"), str):
        out["client"] = request["client"]
    out["request"] = fingerprint_text if fingerprint_text is not None else fingerprint(request)
    return out
