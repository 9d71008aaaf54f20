"""Features attached to the bridge core (issue 44): each lives in its own module with its frozen
config, its CLI flags and an object the bridge attaches (`attach(ctx)`, `start()`, `stop()`).
ORDER lists them in the order they attach; a new feature is its module and its name in ORDER
(docs/architecture.md, "Add a bridge feature")."""

from __future__ import annotations

import importlib

from .base import BridgeContext, Feature, FeatureSpec

__all__ = ["FEATURES", "BridgeContext", "Feature", "FeatureSpec"]

# terrain first: the views it sets are what the CoT sender, the recorder and the log read
ORDER = ("terrain", "cot", "record", "sightings")

FEATURES: tuple[FeatureSpec, ...] = tuple(importlib.import_module(f".{n}", __name__).SPEC for n in ORDER)
