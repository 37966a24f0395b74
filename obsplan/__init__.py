"""obsplan: observability-aware trajectory planning for single-beacon range localisation."""

from __future__ import annotations

__version__ = "0.1.0"
