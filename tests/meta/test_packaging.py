"""Packaging metadata that installs without deprecation warnings."""

from __future__ import annotations

from pathlib import Path

REPO = Path(__file__).resolve().parents[2]


def test_license_is_an_spdx_string():
    """setuptools >= 77 deprecates ``license = {text = ...}`` with a warning at install."""
    import tomllib

    meta = tomllib.loads((REPO / "pyproject.toml").read_text())
    assert meta["project"]["license"] == "MIT"
    assert "setuptools>=77" in meta["build-system"]["requires"]
