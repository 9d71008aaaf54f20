"""Features attached to the bridge core (issue 44): each lives in its own module with its frozen
config, its CLI flags and an object the bridge attaches (`attach(ctx)`, `start()`, `stop()`).
FEATURES lists them in the order they attach; a new feature is its module and one line here
(docs/architecture.md, "Add a bridge feature")."""

from __future__ import annotations

from . import cot, record, terrain
from .base import BridgeContext, Feature, FeatureSpec

__all__ = ["FEATURES", "BridgeContext", "Feature", "FeatureSpec"]

# terrain first: the views it sets are what the CoT sender and the recorder read
FEATURES: tuple[FeatureSpec, ...] = (terrain.SPEC, cot.SPEC, record.SPEC)
