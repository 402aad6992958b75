"""Shared fixtures (designs come from rebarlib.data, the library's data module)."""

from __future__ import annotations

import pytest

from rebarlib.data import paper_design as _paper_design


@pytest.fixture(scope="session")
def paper_design():
    return _paper_design()
