"""A test whose data, build or extra is missing fails in CI (``CI`` set) and skips elsewhere, with a
one-line reason either way (tests/conftest.py: ``missing``, ``needs``, ``import_or_missing``)."""

import pytest

from tests.conftest import import_or_missing, in_ci, missing, needs


@pytest.mark.parametrize("value, expected", [("true", True), ("1", True), ("yes", True), ("", False),
                                             ("false", False), ("0", False), ("No", False)])
def test_ci_is_read_from_the_environment(monkeypatch, value, expected):
    monkeypatch.setenv("CI", value)
    assert in_ci() is expected
    monkeypatch.delenv("CI")
    assert not in_ci()


def test_missing_fails_in_ci_and_skips_elsewhere(monkeypatch):
    monkeypatch.setenv("CI", "true")
    with pytest.raises(pytest.fail.Exception, match=r"^the map is not here \(CI is set"):
        missing("the map is not here")
    with pytest.raises(pytest.fail.Exception, match="no such thing"):
        needs(False, "no such thing")(lambda: None)()
    with pytest.raises(pytest.fail.Exception, match="No module named"):
        import_or_missing("shapelib_no_such_module", "an extra")
    monkeypatch.delenv("CI")
    with pytest.raises(pytest.skip.Exception, match=r"^the map is not here$"):
        missing("the map is not here")
    with pytest.raises(pytest.skip.Exception, match="^no such thing$"):
        needs(False, "no such thing")(lambda: None)()
    with pytest.raises(pytest.skip.Exception, match="^an extra: No module named"):
        import_or_missing("shapelib_no_such_module", "an extra")


def test_an_available_thing_runs_the_test_unchanged():
    def test(x):
        return 2 * x

    assert needs(True, "unused")(test) is test
    assert import_or_missing("math", "unused").sqrt(4.0) == 2.0
