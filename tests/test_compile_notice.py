"""The one-line notice while numba compiles this package's kernels (a cold cache), and only then."""

import io

from numba import njit

from continuum_sim.scenario.compile_notice import NOTICE, compile_notice


def _kernel_of(module: str):
    """A fresh (never compiled) function that numba sees as defined in ``module``."""
    namespace = {"__name__": module}
    exec("def kernel(x):\n    return 2.0 * x + 1.0\n", namespace)  # noqa: S102 - a probe with a chosen __module__
    return njit(cache=False)(namespace["kernel"])


def test_notice_once_when_a_package_kernel_compiles():
    stream = io.StringIO()
    with compile_notice(stream=stream):
        assert _kernel_of("someone_else.module")(1.0) == 3.0  # another package's compile: no notice
        assert stream.getvalue() == ""
        first, second = _kernel_of("continuum_sim.plant.probe"), _kernel_of("continuum_sim.plant.probe")
        first(1.0)
        first(2.0)  # already compiled: no event
        second(1.0)  # a second compile: still one line
    assert stream.getvalue() == NOTICE + "\n"
    _kernel_of("continuum_sim.plant.probe")(1.0)  # after the block: the listener is gone
    assert stream.getvalue() == NOTICE + "\n"


def test_no_notice_when_disabled():
    stream = io.StringIO()
    with compile_notice(enabled=False, stream=stream):
        _kernel_of("continuum_sim.plant.probe")(1.0)
    assert stream.getvalue() == ""
