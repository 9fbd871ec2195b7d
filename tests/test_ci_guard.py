"""The suite's guards: in CI the parity tests cannot silently turn into skips."""

from __future__ import annotations


def test_ci_refuses_to_run_without_the_reference_data(tmp_path):
    from conftest import missing_reference_error

    assert "reference data is missing" in missing_reference_error({"CI": "true"}, None)
    assert missing_reference_error({"CI": "true"}, tmp_path) is None
    assert missing_reference_error({}, None) is None  # locally the parity tests skip with one line
