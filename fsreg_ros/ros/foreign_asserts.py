"""The answer to an ``ltm/assert`` naming a domain no consultant of this graph serves: :class:`ForeignAsserts`.

Such a message would go unanswered (each consultant leaves another domain's assertion to
that domain's consultant), so the WM Manager, which knows the configured domains, answers
it on ``ltm/assert/result``: kind ``unknown-domain``, and ``bad-request`` for a malformed
one.  A message no consultant can read (not JSON, too large) is answered by every
consultant, not here.  The topic is drained like the consultants'
(:func:`~fsreg_ros.ros.batches.subscribe_batches`) and a stream gathered every
:data:`FOREIGN_GATHER` seconds: at a perception stream's rate one executor round per message
cost the WM Manager a quarter to a third of a core for messages it only looks at.  At most
3 ms a round of CPU: ``wm_manager/sync``, which every human turn and REG request waits for,
goes between.
"""

from __future__ import annotations

import time as wallclock
from typing import Any, Iterable, Optional

from .. import contract
from ..contract.codec import printable
from .batches import subscribe_batches
from .carrier import log_warning, publish, publisher

#: Seconds between two takes of a stream of ``ltm/assert`` messages, read only to answer those naming a domain no
#: consultant serves (the first of a stream is taken at once; :func:`~fsreg_ros.ros.batches.subscribe_batches`).
FOREIGN_GATHER = 0.05


class ForeignAsserts:
    """Answers, on ``node``, every ``ltm/assert`` naming none of ``domains``."""

    def __init__(self, node, domains: Iterable[str]) -> None:
        self.node = node
        self.domains = list(domains)
        self.results = publisher(node, contract.LTM_ASSERT_RESULT)
        self.foreign: Optional[str] = None  # the domain of the foreign ltm/assert being handled
        subscribe_batches(node, contract.LTM_ASSERT, self.on_asserts, reject=self.reject, accept=self.accept,
                          limits=contract.Limits(), max_seconds=0.003, clock=wallclock.thread_time,
                          gather=FOREIGN_GATHER)

    def accept(self, data: dict) -> bool:
        """Whether ``data`` names a domain this graph does not have (noted for :meth:`reject`)."""
        domain = data.get("domain")
        self.foreign = domain if isinstance(domain, str) and domain not in self.domains else None
        return self.foreign is not None

    def on_asserts(self, messages: list[dict]) -> None:
        """Answer each ``ltm/assert`` naming a domain this graph does not have (no consultant would)."""
        for data in messages:
            self.foreign = data["domain"]
            self.reject(data.get("id"), printable(
                f"no consultant serves domain {data['domain']!r} (this graph's domains: {', '.join(self.domains)}); "
                "nothing was stored"), "unknown-domain", data["domain"])

    def reject(self, request_id: Any, error: str, kind: str = "bad-request", domain: Optional[str] = None) -> None:
        """Answer the foreign message being handled with ``error`` (nothing if its domain was not known)."""
        foreign, self.foreign = self.foreign, None
        if foreign is None:
            return  # unreadable before its domain was known: the consultants answer it
        reply: dict[str, Any] = {"domain": domain or foreign, "entity": None, "ok": False, "error": error,
                                 "kind": kind}
        if request_id is not None:
            reply["id"] = request_id
        log_warning(self.node.get_logger(), f"{contract.LTM_ASSERT.name}: {error}")
        publish(self.results, reply)
