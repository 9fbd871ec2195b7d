"""Hardness measures of MDPs (see the hardness issue)."""
