"""Type stubs of painterly's native module (re-exported by ``painterly``)."""

import os
from typing import Any, Callable, Protocol, TypeAlias

import numpy as np
import numpy.typing as npt

class _LayerLike(Protocol):
    """A usd-core ``Sdf.Layer``: read from its file when saved (not dirty,
    its ``realPath`` a regular file), else through its text, as unsaved.
    A layer it composes with unsaved edits, or an anonymous one, raises
    ``painterly.Error`` (save it, or pass ``stage.Flatten()``). A
    ``Usd.Stage`` is a ``TypeError``: pass ``stage.GetRootLayer()`` or
    ``stage.Flatten()``."""

    identifier: str
    realPath: str
    dirty: bool
    anonymous: bool
    def ExportToString(self) -> str: ...
    def GetFileFormatArguments(self) -> dict[str, str]: ...
    def GetCompositionAssetDependencies(self) -> list[str]: ...

Input: TypeAlias = str | os.PathLike[str] | _LayerLike
#: "A:B:STEP" as ``--frames``, one frame, or (start, end[, step]); a list of
#: two or three numbers reads as that tuple, never as a list of frames.
Frames: TypeAlias = str | float | tuple[float, float] | tuple[float, float, float]

__version__: str

class Error(Exception):
    """A painterly error; where it is, when known. The message names the
    keyword arguments (``frames``, ``camera``, ``chunk``) where the CLI's
    names its options."""

    message: str
    file: str | None
    prim: str | None
    attribute: str | None
    #: The schema rule broken (``painterly.RULES`` ids), for problems inspect reports.
    rule: str | None

def bake(
    input: Input,
    output: str | os.PathLike[str] | None = None,
    frames: Frames | None = None,
    chunk: int | None = None,
    camera: str | None = None,
    bake_proxy: bool = False,
    progress: Callable[[int, int], Any] | None = None,
) -> dict[str, Any]:
    """Bakes ``input`` into ``output`` (.usdc or .usda) and returns the
    ``painterly bake --json`` summary. Without ``output`` nothing is written:
    the summary's ``"layer"`` holds the baked layer's usda text (see
    ``painterly.to_layer``). ``progress(done, total)`` is called from a worker
    thread as frames are written; an exception it raises is re-raised after
    the bake, which still runs to the end and writes its output. The GIL is
    released while baking. Ctrl-C (in the main thread) stops the bake before
    its next frame and raises ``KeyboardInterrupt``: the output is left as it
    was, and no temporary file remains."""

def inspect(input: Input, camera: str | None = None, frames: Frames | None = None) -> dict[str, Any]:
    """The ``painterly inspect --json [--camera CAMERA] [--frames A:B]`` report;
    ``"problems"`` lists every problem with ``prim``, ``attribute``,
    ``message`` and ``rule``. Without problems, every frame a bake with the
    same ``camera`` and ``frames`` would bake evaluates (a stage without a
    time range needs ``frames``, as ``bake`` does)."""

def _interpolate(
    keys: npt.NDArray[np.float64],
    values: npt.NDArray[np.float64],
    queries: npt.NDArray[np.float64],
    method: str = "smooth_voronoi",
    radius: float = 1.0,
) -> npt.NDArray[np.float64]: ...
def _rules() -> list[tuple[str, str, str]]: ...

class Character:
    """A painted character opened once (rigs, bindings, cameras, view meshes
    resolved); frames are read and evaluated on demand. Stays on the thread
    that opened it: used from another thread it raises pyo3's
    ``PanicException`` (a ``BaseException``, not ``painterly.Error``), so
    open one per thread. Times must be finite numbers."""

    def __init__(self, input: Input, camera: str | None = None) -> None: ...
    @property
    def layers(self) -> list[str]:
        """Stroke layer prim paths, in bake order."""
    @property
    def axes(self) -> list[str]:
        """Axis prim paths (the keys of ``configuration(t)``)."""
    @property
    def view_meshes(self) -> list[str]:
        """View-dependent mesh prim paths."""
    def configuration(self, t: float) -> dict[str, float]:
        """Every axis's value at ``t`` (axis path → value, axis units)."""
    def evaluate(self, t: float, configuration: dict[str, float] | None = None) -> dict[str, npt.NDArray[np.float32]]:
        """Points at ``t`` (prim path → float32 (N, 3)): stroke layers in their
        prim's local space and view-dependent meshes, bit for bit what a bake
        writes. ``configuration`` overrides axis values (what-if)."""
    def opacities(self, t: float, configuration: dict[str, float] | None = None) -> dict[str, npt.NDArray[np.float32]]:
        """Per-curve opacity of every stroke layer at ``t`` (float32 (curves,))."""
