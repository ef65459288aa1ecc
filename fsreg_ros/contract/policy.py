"""The forgetting policy object on the wire, generated from the memory settings table.

``PolicySettings`` is what the WM Manager sends in a consultant's ``configure`` request
(``{"op": "configure", "policy": {...}}``) and what replies and the WM Manager's
services report per domain: ``{"policy": "decay+displacement", "decay_period": 10.0,
"capacity": 2}``.  One field per row of :data:`fsreg_ros.core.forgetting.settings.TABLE` (so a new
memory setting appears here without an edit); unknown keys are refused; every value,
and the whole policy (each rule has its parameters), is checked by the core's rules,
so a model that validates is a policy the core accepts (:meth:`PolicySettings.to_policy`).
"""

from __future__ import annotations

from typing import Any, Optional

from pydantic import Field, create_model, model_validator

from ..core.forgetting import settings
from ..core.forgetting.policies import POLICY_PATTERN, ForgettingPolicy
from .base import Message


class _PolicyBase(Message):
    """The checks of a policy object (the fields come from the settings table)."""

    @model_validator(mode="before")
    @classmethod
    def _known_settings(cls, data: Any) -> Any:
        if isinstance(data, dict):
            unknown = sorted(set(data) - set(settings.names()))
            if unknown:
                raise ValueError(f"unknown memory setting '{unknown[0]}' (known: {', '.join(settings.names())})")
        return data

    @model_validator(mode="after")
    def _a_valid_policy(self) -> "_PolicyBase":
        self.to_policy()  # PolicyError (a ValueError) names what is wrong
        return self

    def to_policy(self) -> ForgettingPolicy:
        """Return the core policy this object describes (PolicyError if it is not one)."""
        return ForgettingPolicy.from_settings({k: v for k, v in self.model_dump().items() if v is not None})


PolicySettings = create_model(
    "PolicySettings",
    __base__=_PolicyBase,
    __doc__="A domain's forgetting policy: ``policy`` (rules joined by +, or none) and the parameters set.",
    **{
        row.name: (row.kind if not row.is_parameter else Optional[row.kind],
                   Field(... if not row.is_parameter else None, description=row.description,
                         json_schema_extra=row.json_schema_extra(POLICY_PATTERN)))
        for row in settings.TABLE
    },
)
