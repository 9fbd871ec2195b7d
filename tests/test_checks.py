"""The shared argument checks' unknown-name hint (jaxmdp/_checks.py)."""

from jaxmdp._checks import did_you_mean


def test_did_you_mean_names_the_closest_known_names_in_order():
    known = {"gaussian": 0, "correlated_gaussian": 1, "student_t": 2}  # any iterable of names, e.g. a dict's keys
    assert did_you_mean("gausian", known) == "; did you mean 'gaussian', 'correlated_gaussian'?"
    assert did_you_mean("studnt_t", known) == "; did you mean 'student_t'?"
    assert did_you_mean("xyz", known) == ""
    # The cutoff is difflib's ratio: 'gaussian' vs 'gauss' is 2 * 5 / 13 = 0.769.
    assert did_you_mean("gauss", ["gaussian"], 0.769) == "; did you mean 'gaussian'?"
    assert did_you_mean("gauss", ["gaussian"], 0.77) == ""
    assert did_you_mean("a", [f"a{i}" for i in range(10)], 0.1).count("'") == 6  # at most three names
