"""The paper's benchmark (§4, App. B): the 80 MDPs of its four settings as data (:mod:`hardness.benchmark.suite`).

Not imported by :mod:`hardness`; like :mod:`hardness.analysis` it sits above the measures and may import
:mod:`agents`.
"""
