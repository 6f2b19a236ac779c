"""bench.hostile's /api/health wait statistics: nearest-rank p99, never below the median."""

from bench.hostile import wait_stats


def test_p99_is_a_nearest_rank_and_never_below_the_median():
    two = wait_stats([0.004, 0.001])
    assert two == {"health_calls": 2, "health_p50_ms": 2.5, "health_p99_ms": 4.0, "health_max_ms": 4.0}
    hundred = wait_stats([i / 1e3 for i in range(1, 101)], prefix="")
    assert hundred["p99_ms"] == 99.0 and hundred["p50_ms"] == 50.5


def test_no_waits_give_no_figures():
    assert wait_stats([]) == {"health_calls": 0, "health_p50_ms": None, "health_p99_ms": None, "health_max_ms": None}
