"""The names of the measured materials the tests run on (the files come from the
``materials_dir`` fixture; they are never copied into the repository)."""

from __future__ import annotations

MEASURED = (
    "bluebook",
    "green-plastic",
    "red-plastic",
    "red-specular-plastic",
    "satin_gold",
    "spectralon",
    "specular-orange-phenolic",
)
