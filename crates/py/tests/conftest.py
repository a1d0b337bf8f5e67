"""Shared data for the physid package's tests: the repository's golden files."""
import pathlib

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[3]


@pytest.fixture
def golden():
    """A golden file of the repository by its path from the root."""
    return lambda rel: ROOT / rel
