"""obsplan: observability-aware trajectory planning for single-beacon range localisation."""

from __future__ import annotations

__version__ = "0.1.0"

from obsplan.observability.analyze import ObservabilityReport, analyze  # noqa: E402

__all__ = ["ObservabilityReport", "__version__", "analyze"]
