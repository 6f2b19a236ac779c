"""The stability catalogue: cases (``cases.py``), their evaluation and report (``catalogue.py``),
the test (``test_catalogue.py``) and the writer of ``docs/STABILITY.md`` (``write.py``)."""
