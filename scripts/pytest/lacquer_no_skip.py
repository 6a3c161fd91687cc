"""pytest plugin: a skipped test is a failure unless skipping is allowed.

Loaded by scripts/test.sh (and the sub-suites' test.sh) with ``-p lacquer_no_skip``. A test
that cannot run here (no Mitsuba variant, no libLLVM, no bpy, a model not registered) would
otherwise pass CI silently. ``LACQUER_ALLOW_SKIP=1`` allows skips on a developer machine; it is
ignored when ``CI=true`` (``.ci/run``). Expected failures (xfail) are not skips and keep their
meaning.
"""

import os

import pytest


def skips_allowed():
    """True when a skip may stay a skip: LACQUER_ALLOW_SKIP=1 and not in CI."""
    return os.environ.get("LACQUER_ALLOW_SKIP") == "1" and os.environ.get("CI", "").lower() not in ("true", "1")


def _reason(rep):
    if isinstance(rep.longrepr, tuple) and len(rep.longrepr) == 3:
        return rep.longrepr[2]
    return str(rep.longrepr)


def _fail(rep):
    rep.outcome = "failed"
    rep.longrepr = (
        f"skipped, and a skip fails this run: {_reason(rep)}\n"
        "(LACQUER_ALLOW_SKIP=1 allows skips outside CI; CI=true never does)"
    )


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    outcome = yield
    rep = outcome.get_result()
    if rep.skipped and not hasattr(rep, "wasxfail") and not skips_allowed():
        _fail(rep)


@pytest.hookimpl(hookwrapper=True)
def pytest_make_collect_report(collector):
    outcome = yield
    rep = outcome.get_result()
    if rep.skipped and not skips_allowed():
        _fail(rep)


def pytest_report_header(config):
    allowed = "allowed (LACQUER_ALLOW_SKIP=1)" if skips_allowed() else "fail the run"
    return f"lacquer_no_skip: skipped tests {allowed}"
