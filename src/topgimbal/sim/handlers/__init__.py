"""What each identifier does, one module per subsystem, and the tables that say which handler
answers which identifier of a dialect (`handler_table`). Handlers see only `context.SimState`."""

from __future__ import annotations

from .tables import BY_ROLE, DIALECT_TABLES, handler_table

__all__ = ["BY_ROLE", "DIALECT_TABLES", "handler_table"]
