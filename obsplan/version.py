"""The package version (one place: the facade, the CLI and the sweep manifests read it here)."""

from __future__ import annotations

__version__ = "0.1.0"
