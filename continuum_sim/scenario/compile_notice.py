"""One line on stderr when a run has to compile the physics kernels (numba's cache lacks them).

The kernels (cable path and friction, cutter, control tick) are compiled by numba on first use
and cached on disk (``NUMBA_CACHE_DIR``, else ``__pycache__`` beside the sources). On a fresh
clone, a new CPU target or after a kernel's source changed, the first run compiles them: about
30 s of CPU (docs/speed.md) during which nothing else moves. numba broadcasts a
``"numba:compile"`` event only when it compiles, not when it loads from its cache, so listening
for it tells exactly when to say why the run is quiet.
"""

from __future__ import annotations

import sys
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any, TextIO

NOTICE = "compiling the physics kernels once (~30 s); later runs load them from numba's cache"
PACKAGE = __name__.split(".")[0]


def _listener(stream: TextIO) -> Any:
    """A numba event listener that writes ``NOTICE`` when it first sees one of this package's kernels compile."""
    from numba.core.event import Listener  # lazily: numba only where a run is made

    class FirstCompile(Listener):
        noticed = False

        def on_start(self, event: Any) -> None:
            dispatcher = (event.data or {}).get("dispatcher")
            module = getattr(getattr(dispatcher, "py_func", None), "__module__", "") or ""
            if not self.noticed and (module == PACKAGE or module.startswith(PACKAGE + ".")):
                self.noticed = True
                from tqdm import tqdm

                tqdm.write(NOTICE, file=stream)  # above a progress bar, if one is drawn

        def on_end(self, event: Any) -> None:
            pass

    return FirstCompile()


@contextmanager
def compile_notice(enabled: bool = True, stream: TextIO | None = None) -> Iterator[None]:
    """While the block runs, say once (to ``stream``, default stderr) that the kernels are being compiled."""
    if not enabled:
        yield
        return
    from numba.core import event

    with event.install_listener("numba:compile", _listener(sys.stderr if stream is None else stream)):
        yield
