"""The extension module imports and reports the crate's version."""

import re

import lgdm


def test_version_is_semver():
    assert re.fullmatch(r"\d+\.\d+\.\d+", lgdm.__version__)
