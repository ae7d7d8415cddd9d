"""The slowest tests of a run (``tests/conftest.py`` keeps them where ``VLIGHTS_DURATIONS`` says)."""

SLOWEST = 20  # the slowest tests a run keeps (``VLIGHTS_DURATIONS=FILE``)


def slowest_tests(reports, count=SLOWEST):
    """[{"test", "phase", "seconds"}] of the ``count`` slowest phases (setup, call,
    teardown) among pytest's ``reports``, slowest first."""
    rows = [{"test": r.nodeid, "phase": r.when, "seconds": round(float(r.duration), 3)} for r in reports
            if getattr(r, "duration", None) is not None and getattr(r, "when", None)]
    return sorted(rows, key=lambda row: -row["seconds"])[:count]
