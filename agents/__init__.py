"""Tabular agents as pure functions over pytrees (see the agents issue)."""
