"""The tests mirror the code: tests/renderer/{,accel/,gl/}test_<module>.py, tests/bench/, ….

Packages (with ``__init__.py``) so that under pytest's default ``prepend`` import mode
every test module has a unique dotted name (``tests.renderer.gl.test_ray_engine`` is not
``tests.renderer.accel.test_ray_engine``) and ``tests/renderer/`` can never shadow the
``renderer`` package being tested. ``tests/server/`` and ``tests/browser/`` stay plain
directories: their modules import their support modules by bare name.
"""
