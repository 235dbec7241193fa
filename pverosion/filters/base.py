"""The filter contract shared by every pverosion stage.

A stage is a :class:`~vtkmodules.util.vtkAlgorithm.VTKPythonAlgorithmBase`
subclass that declares its options once, as :class:`Param` metadata. From that
metadata the base class generates the VTK-style ``SetName``/``GetName``
methods (which call ``Modified()`` only on change); the CLI, the PyVista
accessor and the ParaView plugin generator read the same metadata, so an
option is written in one place.
"""

from __future__ import annotations

import math
import signal
import threading
from collections.abc import Callable, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
from vtkmodules.util import numpy_support
from vtkmodules.util.vtkAlgorithm import VTKPythonAlgorithmBase
from vtkmodules.vtkCommonCore import vtkIdTypeArray, vtkObject, vtkStringArray
from vtkmodules.vtkCommonDataModel import vtkCellArray, vtkMultiBlockDataSet, vtkPolyData
from vtkmodules.vtkCommonExecutionModel import vtkStreamingDemandDrivenPipeline as SDDP

from pverosion._runtime import stage_run
from pverosion.kernels.validation import InvalidMeshError, as_faces, as_points, check_coordinate_precision
from pverosion.limits import check_memory

__all__ = [
    "ErosionFilter",
    "Param",
    "TimeSteppedFilter",
    "check_axis_aligned",
    "check_interrupt",
    "deferred_interrupt",
    "numbers_text",
    "output_times",
    "parse_numbers",
    "polydata_triangle_mesh",
    "polydata_triangles",
    "replace_triangles",
    "set_field_value",
    "set_multiblock",
    "set_point_array",
]


@dataclass(frozen=True)
class Param:
    """One option of a filter.

    Parameters
    ----------
    name : str
        snake_case keyword used by Python front ends (``normalization``);
        the VTK methods are ``Set``/``Get`` + CamelCase (``SetNormalization``).
    default : bool, int, float or str
        Default value; its type is the option's type.
    doc : str
        One-line description shown in docstrings, ``--help`` and ParaView.
    choices : tuple of str, optional
        Allowed values of a string option.
    minimum, maximum : float, optional
        Inclusive bounds of a numeric option.
    path : {"input", "output"}, optional
        The option names a file the filter reads (``"input"``) or writes
        (``"output"``); batch runs resolve such paths (see :mod:`pverosion.batch`).
    numbers : int, optional
        A string option holding comma-separated finite numbers: exactly this
        many, or one or more when 0. Checked when set (empty means unset).
    parse : callable, optional
        ``parse(text)`` of a string option, raising ``ValueError`` for a bad
        non-empty value; called when the option is set, so every front end
        refuses it before running.
    convert : callable, optional
        Makes a string option *structured* (emitters, drains): ``convert(value)``
        turns its text or a Python value (the kernel's dataclass, a sequence of
        them) into the checked structured value, raising ``ValueError`` or
        ``TypeError``. Python front ends pass such values through unchanged;
        read them with :meth:`ErosionFilter.structured_option`.
    format : callable, optional
        ``format(structured value) -> text``, the inverse of ``convert`` for
        text front ends (batch records, ``--help``).
    python_type : str
        Type of the option in the Python front ends' docstrings (default:
        derived from the default, ``choices`` and ``numbers``).
    units : str
        Units of a quantity (``"m/s"``, ``"Pa"``; ``"model units"`` for
        lengths in the mesh's units); empty for a pure number.
    advanced : bool
        Solver tuning: ParaView shows it only in the advanced panel.
    """

    name: str
    default: Any
    doc: str
    choices: tuple[str, ...] | None = None
    minimum: float | None = None
    maximum: float | None = None
    path: str | None = None
    numbers: int | None = None
    parse: Callable[[str], Any] | None = None
    convert: Callable[[Any], Any] | None = None
    format: Callable[[Any], str] | None = None
    python_type: str = ""
    units: str = ""
    advanced: bool = False

    def __post_init__(self) -> None:
        if (self.convert is None) != (self.format is None):
            raise ValueError(f"option {self.name}: a structured option needs both convert and format")
        if self.numbers is not None and self.convert is not None:
            raise ValueError(f"option {self.name}: an option is a vector (numbers) or structured (convert), not both")

    @property
    def kind(self) -> type:
        """Python type of the option (bool, int, float or str)."""
        return type(self.default)

    @property
    def help(self) -> str:
        """The description with the units, as ``--help``, ParaView and the docstrings show it."""
        return f"{self.doc} [{self.units}]" if self.units else self.doc

    @property
    def camel(self) -> str:
        """CamelCase name used by the VTK methods and ParaView properties."""
        return "".join(part.capitalize() for part in self.name.split("_"))

    @property
    def python_default(self) -> Any:
        """Default in the Python front ends: a tuple of floats for a vector, None for an unset vector or structure."""
        if self.numbers is not None or self.convert is not None:
            if not self.default:
                return None
            if self.numbers is not None:
                return tuple(parse_numbers(self.default, self.name, count=self.numbers or None))
            return self.convert(self.default)
        return self.default

    def text(self, value: Any) -> str:
        """The text form of a valid value of this option (for the command line and batch records)."""
        value = self.validate(value)
        if self.convert is not None and not isinstance(value, str):
            return self.format(value)
        return str(value)

    def validate(self, value: Any) -> Any:
        """Return ``value`` converted to the option's type, or raise ``ValueError``/``TypeError``.

        A vector option (``numbers``) also takes a sequence of numbers, kept
        as its text ``"x,y,z"``; a vector or structured option takes None
        for unset. A structured option (``convert``) keeps a non-text value
        as ``convert(value)``, so Python objects are never turned into text.
        """
        if value is None and (self.numbers is not None or self.convert is not None):
            return ""
        if self.numbers is not None and not isinstance(value, str):
            value = self._vector_text(value)  # checked as its text below
        if self.convert is not None and not isinstance(value, str):
            try:
                return self.convert(value)
            except (ValueError, TypeError) as exc:
                message = str(exc)
                raise type(exc)(message if message.startswith(self.name) else f"{self.name}: {message}") from None
        kind = self.kind
        if kind is bool:
            if not isinstance(value, (bool, np.bool_, int, np.integer)) or value not in (0, 1):
                raise TypeError(f"{self.name} must be a bool; got {value!r}")
            return bool(value)
        if kind in (int, float):
            if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer, np.floating)):
                raise TypeError(f"{self.name} must be a number; got {value!r}")
            if isinstance(value, (float, np.floating)) and not np.isfinite(value):
                raise ValueError(f"{self.name} must be finite; got {value!r}")
            if kind is int and isinstance(value, (float, np.floating)) and not float(value).is_integer():
                raise TypeError(f"{self.name} must be an integer; got {value!r}")
            try:
                value = kind(value)  # an integer stays exact, however large; a float option may overflow
            except OverflowError:
                raise ValueError(f"{self.name} must be finite; got {value!r}") from None
            if kind is int and not -(2**63) <= value < 2**63:  # the kernels take 64-bit integers
                raise ValueError(f"{self.name} must be a 64-bit integer (at most {2**63 - 1}); got {value!r}")
            if self.minimum is not None and value < self.minimum:
                raise ValueError(f"{self.name} must be >= {self.minimum}; got {value!r}")
            if self.maximum is not None and value > self.maximum:
                raise ValueError(f"{self.name} must be <= {self.maximum}; got {value!r}")
            return value
        if not isinstance(value, str):
            raise TypeError(f"{self.name} must be a string; got {value!r}")
        if self.choices is not None and value not in self.choices:
            raise ValueError(f"{self.name} must be one of {self.choices}; got {value!r}")
        if value and self.numbers is not None:
            parse_numbers(value, self.name, count=self.numbers or None)
        if value and self.parse is not None:
            try:
                self.parse(value)
            except (ValueError, TypeError) as exc:
                message = str(exc)
                raise ValueError(message if message.startswith(self.name) else f"{self.name}: {message}") from None
        return value


    def _vector_text(self, value: Any) -> str:
        """The canonical text ``"x,y,z"`` of a sequence of numbers given for a vector option."""
        try:
            values = np.asarray(value, dtype=np.float64).ravel()
        except (TypeError, ValueError):
            raise TypeError(f"{self.name} must be numbers or their text 'x,y,z'; got {value!r}") from None
        if np.asarray(value).ndim == 0:
            raise TypeError(f"{self.name} must be a sequence of numbers; got {value!r}")
        if self.numbers and values.size != self.numbers:
            raise ValueError(f"{self.name} needs {self.numbers} numbers; got {values.size}")
        if values.size == 0:
            raise ValueError(f"{self.name} needs at least one number")
        if not np.isfinite(values).all():
            raise ValueError(f"{self.name} must be finite numbers; got {value!r}")
        return numbers_text(values)


def numbers_text(values) -> str:
    """The text ``"x,y,z"`` of numbers, exact (``repr``) so :func:`parse_numbers` reads the same floats back."""
    return ",".join(repr(float(v)) for v in values)


def parse_numbers(text: str, name: str, *, count: int | None = None) -> list[float]:
    """Comma- or space-separated numbers of a string option (exactly ``count`` if given); ``ValueError`` naming it."""
    try:
        values = [float(v) for v in text.replace(",", " ").split()]
    except ValueError:
        raise ValueError(f"{name} must be numbers separated by commas; got {text!r}") from None
    if not values:
        raise ValueError(f"{name} needs at least one number")
    if not all(math.isfinite(v) for v in values):
        raise ValueError(f"{name} must be finite numbers; got {text!r}")
    if count is not None and len(values) != count:
        raise ValueError(f"{name} needs {count} numbers; got {len(values)} in {text!r}")
    return values


class ErosionFilter(VTKPythonAlgorithmBase):
    """Base class of all pverosion filters (one input port unless ``INPUT_PORTS`` names more, one output port).

    Subclasses set ``PARAMS``, ``LABEL`` and implement :meth:`execute`, which
    gets one input data object per port, then the output.
    Keyword arguments of the constructor set options by their snake_case name.

    Any exception (``BaseException``, so ``KeyboardInterrupt`` too) raised in
    a pipeline pass (information, update extent, data) is kept in
    :attr:`last_error` and re-raised by :meth:`run` after ``Update()`` (VTK
    itself would only print it); a plain VTK pipeline sees the usual
    "returned failure" error from the executive and can read
    :attr:`last_error`.
    """

    PARAMS: ClassVar[tuple[Param, ...]] = ()
    LABEL: ClassVar[str] = ""
    COMMAND: ClassVar[str] = ""
    """CLI subcommand; the lower-case class name when empty."""
    TIME_DEPENDENT: ClassVar[bool] = False
    """Whether the output publishes TIME_STEPS (one per simulation step)."""
    REQUIRED: ClassVar[dict[str, str]] = {}
    """Options a run cannot do without, with an example value: a batch scenario is checked for them before
    any job runs (the filter itself refuses a run without them)."""
    INPUT_TYPE: ClassVar[str] = "vtkPolyData"
    """Data type of every input port."""
    INPUT_PORTS: ClassVar[tuple[str, ...]] = ("Input",)
    """Names of the input ports, in port order (ParaView input properties; CLI positional arguments)."""
    OUTPUT_TYPE: ClassVar[str] = "vtkPolyData"

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        for param in cls.PARAMS:
            setter, getter = f"Set{param.camel}", f"Get{param.camel}"
            if setter not in cls.__dict__:
                setattr(cls, setter, _make_setter(param.name))
            if getter not in cls.__dict__:
                setattr(cls, getter, _make_getter(param.name))

    def __init__(self, **options):
        VTKPythonAlgorithmBase.__init__(
            self, nInputPorts=len(self.INPUT_PORTS), inputType=self.INPUT_TYPE, nOutputPorts=1, outputType=self.OUTPUT_TYPE
        )
        self._values = {p.name: p.default for p in self.PARAMS}
        self._error: BaseException | None = None
        self.last_error: BaseException | None = None
        """The exception of the last failed pipeline pass (None again after a successful update)."""
        for name, value in options.items():
            self.set_option(name, value)

    @classmethod
    def command_name(cls) -> str:
        """Name of the stage on the command line and in batch scenarios (``COMMAND`` or the lower-case class name)."""
        return cls.COMMAND or cls.__name__.lower()

    @classmethod
    def param(cls, name: str) -> Param:
        """The :class:`Param` called ``name``; ``TypeError`` naming the known options otherwise."""
        for p in cls.PARAMS:
            if p.name == name:
                return p
        known = ", ".join(p.name for p in cls.PARAMS) or "none"
        raise TypeError(f"{cls.__name__} has no option {name!r} (options: {known})")

    def set_option(self, name: str, value: Any) -> None:
        """Set option ``name``; calls ``Modified()`` only when the value changes."""
        value = self.param(name).validate(value)
        if self._values[name] != value:
            self._values[name] = value
            self.Modified()

    def get_option(self, name: str) -> Any:
        """Current value of option ``name``."""
        self.param(name)
        return self._values[name]

    def structured_option(self, name: str) -> Any:
        """Value of a structured option (``Param.convert``), whether it was set as text or as Python objects."""
        p = self.param(name)
        value = self._values[name]
        return p.convert(value) if p.convert is not None and isinstance(value, str) else value

    @property
    def options(self) -> dict[str, Any]:
        """All option values by snake_case name."""
        return dict(self._values)

    def _guarded(self, work: Callable[[], Any]) -> int:
        """Run one pipeline pass; keep any exception for :meth:`run_time` and return VTK's 0 (failure) or 1."""
        try:
            work()
        except BaseException as exc:  # noqa: BLE001 - kept and re-raised by run_time(); VTK would only print it
            if self._error is None:
                self._error = exc
            self.last_error = exc
            return 0
        return 1

    def RequestInformation(self, request, in_info, out_info):
        """Publish the output's meta-data (:meth:`information`); errors are kept, see :meth:`run`."""
        return self._guarded(lambda: self.information(out_info.GetInformationObject(0)))

    def information(self, info) -> None:
        """Fill the output information object ``info`` (meta-data such as TIME_STEPS); nothing by default."""
        check_interrupt()

    def RequestUpdateExtent(self, request, in_info, out_info):
        """Pass the request upstream unchanged; errors are kept, see :meth:`run`."""
        return self._guarded(check_interrupt)

    def RequestData(self, request, in_info, out_info):
        """Run :meth:`execute` on the input data object(s) and the output data object."""
        def work():
            inputs = [self.GetInputData(in_info, port, 0) for port in range(len(self.INPUT_PORTS))]
            out = self.GetOutputData(out_info, 0)
            self.UpdateProgress(0.0)
            with stage_run(self.command_name(), inputs[0].GetNumberOfPoints()):  # threads by size; compile notice
                self.execute(*inputs, out)
            self.UpdateProgress(1.0)

        status = self._guarded(work)
        if status:
            self.last_error = None
        return status

    def UpdateProgress(self, amount: float) -> None:
        """Report progress ``amount`` in [0, 1]; raise ``KeyboardInterrupt`` here when one is pending.

        Stages call this between their steps, so a deferred interrupt (see
        :func:`deferred_interrupt`) stops a run within one step.
        """
        super().UpdateProgress(amount)
        check_interrupt()

    def execute(self, inp, out) -> None:
        """Fill ``out`` from ``inp`` (one argument per input port); implemented by each stage."""
        raise NotImplementedError

    def run(self, data, *others):
        """Execute on ``data`` and return a new output object; raise the error of a failed run.

        Parameters
        ----------
        data : vtkDataObject
            Input data object (PyVista datasets are VTK objects too).
        *others : vtkDataObject
            The inputs of the further ports of a filter with several (``INPUT_PORTS``).

        Returns
        -------
        vtkDataObject
            A new object, independent of this filter's later updates.

        Raises
        ------
        TypeError
            If the number of inputs is not the number of input ports.
        """
        return self.run_time(data, None, *others)

    def run_time(self, data, time: float | None, *others):
        """Like :meth:`run`, at output time ``time`` of a time-dependent filter (None: the default).

        The inputs stay connected, so a time-dependent filter can continue
        from its cached state when a later time is asked for.
        """
        inputs = (data, *others)
        if len(inputs) != len(self.INPUT_PORTS):
            raise TypeError(f"{type(self).__name__} takes {len(self.INPUT_PORTS)} input(s) "
                            f"({', '.join(self.INPUT_PORTS)}); got {len(inputs)}")
        for port, obj in enumerate(inputs):
            if self.GetInputDataObject(port, 0) is not obj:
                self.SetInputDataObject(port, obj)
        shown = vtkObject.GetGlobalWarningDisplay()
        vtkObject.GlobalWarningDisplayOff()
        self._error = None  # what this update raises, in any pass
        try:
            if time is None:
                self.Update()
            else:
                self.UpdateTimeStep(float(time))
        finally:
            vtkObject.SetGlobalWarningDisplay(shown)
        if self._error is not None:
            error, self._error = self._error, None
            raise error
        check_interrupt()
        result = self.GetOutputDataObject(0).NewInstance()
        result.ShallowCopy(self.GetOutputDataObject(0))
        return result

    def step_through(
        self,
        data,
        times: Sequence[float],
        *,
        on_output: Callable[[float, Any], None] | None = None,
        on_progress: Callable[[float], None] | None = None,
    ):
        """Run a time-dependent filter to each of the increasing ``times`` in turn.

        Parameters
        ----------
        data : vtkDataObject
            Input data object.
        times : sequence of float
            Output times, increasing; each run continues from the cached state.
        on_output : callable, optional
            ``on_output(time, output)`` after each time is reached.
        on_progress : callable, optional
            ``on_progress(t)`` with the fractional time reached so far, as the
            filter reports progress.

        Returns
        -------
        vtkDataObject
            The output at the last time.
        """
        result = None
        reached = 0.0
        for t in times:
            tag = None
            if on_progress is not None:
                def relay(caller, _event, start=reached, stop=t):
                    if self._error is None:  # VTK reports progress 1 after a failed pass too
                        on_progress(start + caller.GetProgress() * (stop - start))

                tag = self.AddObserver("ProgressEvent", relay)
            try:
                result = self.run_time(data, t)
            finally:
                if tag is not None:
                    self.RemoveObserver(tag)
            reached = t
            if on_progress is not None:
                on_progress(t)
            if on_output is not None:
                on_output(t, result)
        return result


def output_times(iterations: int, save_every: int | None) -> range | list[int]:
    """Steps to output: every ``save_every``-th of 0..iterations and the last (only the last when None/0).

    The steps are produced lazily (a ``range``, with the last step appended
    when ``save_every`` does not divide ``iterations``), so a long run never
    holds a list of its steps.

    Raises
    ------
    ValueError
        If ``save_every`` is negative.
    """
    if save_every is not None and save_every < 0:
        raise ValueError(f"save_every must be >= 0; got {save_every}")
    if not save_every:
        return [iterations]
    steps = range(0, iterations + 1, save_every)
    return steps if steps[-1] == iterations else _Appended(steps, iterations)


class _Appended(Sequence):
    """A range followed by one more value, as a lazy sequence."""

    def __init__(self, head: range, last: int):
        self.head, self.last = head, last

    def __len__(self) -> int:
        return len(self.head) + 1

    def __getitem__(self, index):
        if isinstance(index, slice):
            return [self[i] for i in range(*index.indices(len(self)))]
        if index < 0:
            index += len(self)
        if not 0 <= index < len(self):
            raise IndexError(index)
        return self.head[index] if index < len(self.head) else self.last


class TimeSteppedFilter(ErosionFilter):
    """An iterative stage: publishes TIME_STEPS 0..iterations (time n = step n).

    Subclasses need an ``iterations`` option; :meth:`requested_step` tells
    :meth:`execute` which step the pipeline asked for (the last when no time
    was requested).
    """

    TIME_DEPENDENT = True

    def __init__(self, **options):
        super().__init__(**options)
        self._time: float | None = None

    def information(self, info) -> None:
        """Publish the time steps 0..iterations, after checking that their list fits in memory."""
        super().information(info)
        n = self.get_option("iterations")
        # the steps are held as doubles by NumPy, by VTK's information and by any consumer's copy
        check_memory(3 * 8 * (n + 1), option="iterations", what=f"the list of {n + 1} time steps")
        info.Set(SDDP.TIME_STEPS(), np.arange(n + 1, dtype=np.float64), n + 1)
        info.Set(SDDP.TIME_RANGE(), [0.0, float(n)], 2)

    def RequestData(self, request, in_info, out_info):
        """Read the requested time, then run :meth:`execute`."""
        info = out_info.GetInformationObject(0)
        self._time = info.Get(SDDP.UPDATE_TIME_STEP()) if info.Has(SDDP.UPDATE_TIME_STEP()) else None
        return super().RequestData(request, in_info, out_info)

    def execute(self, inp, out) -> None:
        """Advance (or restart) the cached solver to the requested step, then fill ``out`` from it.

        The one execution of every time-stepped stage: the solver
        (:class:`~pverosion.kernels.solver.protocol.Solver`) comes from :meth:`_new_solver` and is kept
        between updates (:meth:`cached_solver`), progress is reported after every step, and a pending
        Ctrl-C stops the run between two steps.
        """
        step = self.requested_step()
        solver, _ = self.cached_solver(inp, step, self._new_solver)
        start = solver.step_count
        total = max(step - start, 1)

        def progress(s) -> None:
            self.UpdateProgress(min((s.step_count - start) / total, 1.0))

        solver.run(step - start, outputs=[step], on_step=progress)
        self._fill(solver, inp, out)
        out.GetInformation().Set(out.DATA_TIME_STEP(), float(step))

    def _new_solver(self, inp):
        """A new solver for input ``inp`` at step 0; implemented by each stage."""
        raise NotImplementedError

    def _fill(self, solver, inp, out) -> None:
        """Fill ``out`` from the solver's current state; implemented by each stage."""
        raise NotImplementedError

    def cached_solver(self, inp, step: int, build: Callable[[Any], Any]) -> tuple[Any, bool]:
        """The solver kept from the last update, or ``build(inp)`` when it cannot continue to ``step``.

        A new solver is built when there is none, when the input or the
        options changed since it was built, or when it has gone past
        ``step`` (its ``step_count``). Returns ``(solver, is_new)``.
        """
        key = (inp.GetMTime(), self.GetMTime())
        solver = getattr(self, "_cached", None)
        if solver is None or self._cached_key != key or solver.step_count > step:
            self._cached = None  # free the old solver before building the next
            self._cached, self._cached_key = build(inp), key
            return self._cached, True
        return solver, False

    def requested_step(self) -> int:
        """The step the pipeline asked for, rounded and clamped to 0..iterations."""
        n = self.get_option("iterations")
        return n if self._time is None else round(min(max(self._time, 0.0), float(n)))


class _Interrupt:
    pending = False


def check_interrupt() -> None:
    """Raise ``KeyboardInterrupt`` if Ctrl-C was pressed inside :func:`deferred_interrupt`."""
    if _Interrupt.pending:
        _Interrupt.pending = False
        raise KeyboardInterrupt


@contextmanager
def deferred_interrupt():
    """Context manager: the first Ctrl-C (SIGINT) only marks an interrupt, raised at the next step boundary.

    Stages check at every :meth:`ErosionFilter.UpdateProgress` and at the end
    of each pass, so a run stops within one step at a point where its state is
    whole, and the interrupt reaches the caller as ``KeyboardInterrupt``
    through the usual error path. A second Ctrl-C interrupts at once. Outside
    the main thread this does nothing.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def mark(signum, frame):
        if _Interrupt.pending:  # second Ctrl-C: stop now
            signal.default_int_handler(signum, frame)
        _Interrupt.pending = True

    previous = signal.signal(signal.SIGINT, mark)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
        pending, _Interrupt.pending = _Interrupt.pending, False
    if pending:
        raise KeyboardInterrupt


def _make_setter(name):
    def setter(self, value):
        self.set_option(name, value)

    setter.__name__ = f"Set{name}"
    setter.__doc__ = f"Set option ``{name}``."
    return setter


def _make_getter(name):
    def getter(self):
        return self.get_option(name)

    getter.__name__ = f"Get{name}"
    getter.__doc__ = f"Return option ``{name}``."
    return getter


def check_axis_aligned(image) -> None:
    """``ValueError`` for a vtkImageData whose axes are turned against x, y and z (a direction matrix other than
    the identity, as DICOM and some medical exports carry).

    The stages place an image's samples at ``origin + index * spacing``; a
    turned image would be built, eroded or sampled at the wrong places. The
    message names the way to use it anyway: reset the direction and turn the
    results about the origin by the same matrix.
    """
    matrix = image.GetDirectionMatrix()
    direction = np.array([[matrix.GetElement(i, j) for j in range(3)] for i in range(3)])
    if not np.array_equal(direction, np.eye(3)):
        rows = "; ".join(", ".join(f"{v:.6g}" for v in row) for row in direction)
        raise ValueError(f"the image's axes are turned against x, y and z (direction matrix [{rows}]), which the "
                         "stages do not follow: set its direction to the identity (image.direction_matrix = "
                         "numpy.eye(3) in PyVista, SetDirectionMatrix in VTK) and turn the results about the "
                         "image's origin by the same matrix")


def polydata_triangles(mesh: vtkPolyData) -> tuple[np.ndarray, np.ndarray]:
    """Points (V, 3) and triangles (F, 3) of a vtkPolyData, without copying where possible.

    The one place where the stages take a surface's points from VTK, in the
    type they are stored in: points stored in a type too coarse for the mesh's
    edges (float32 far from the origin) are warned about here
    (:func:`~pverosion.kernels.validation.check_coordinate_precision`), once
    the points are known to be finite.

    Warns
    -----
    UserWarning
        If the rounding step of the stored coordinates exceeds
        :data:`~pverosion.kernels.validation.COORDINATE_STEP_FRACTION` of the
        median edge length.

    Raises
    ------
    InvalidMeshError
        If the mesh has no points, points with NaN or infinite coordinates,
        no polygons, triangle strips, or polygons that are not triangles.
    """
    points, faces = _stored_triangles(mesh)
    if not np.isfinite(points).all():
        as_points(points)  # raises InvalidMeshError naming the vertices
    check_coordinate_precision(points, faces)
    return points, faces


def _stored_triangles(mesh: vtkPolyData) -> tuple[np.ndarray, np.ndarray]:
    """The points (V, 3), in their stored type, and triangles (F, 3) of a vtkPolyData, as views; the checks of
    :func:`polydata_triangles` but those of the coordinates."""
    if mesh is None or not isinstance(mesh, vtkPolyData):
        raise InvalidMeshError(f"expected a vtkPolyData surface; got {type(mesh).__name__}")
    if mesh.GetNumberOfPoints() == 0:
        raise InvalidMeshError("mesh is empty: it has no points")
    if mesh.GetNumberOfStrips() > 0:
        raise InvalidMeshError("mesh has triangle strips: triangulate it first (mesh.triangulate())")
    polys = mesh.GetPolys()
    if polys.GetNumberOfCells() == 0:
        raise InvalidMeshError("mesh has no polygons (only vertices or lines)")
    offsets = numpy_support.vtk_to_numpy(polys.GetOffsetsArray())
    sizes = np.diff(offsets)
    if np.any(sizes != 3):
        bad = int(np.count_nonzero(sizes != 3))
        raise InvalidMeshError(
            f"mesh has {bad} polygons that are not triangles (sizes {sorted(set(sizes.tolist()))}): "
            "triangulate it first (mesh.triangulate())"
        )
    faces = numpy_support.vtk_to_numpy(polys.GetConnectivityArray()).reshape(-1, 3)
    return numpy_support.vtk_to_numpy(mesh.GetPoints().GetData()), faces


def polydata_triangle_mesh(mesh: vtkPolyData) -> tuple[np.ndarray, np.ndarray]:
    """Points (V, 3) as contiguous float64 and triangles (F, 3) as contiguous int64, checked once.

    :func:`polydata_triangles` followed by the checks of
    :func:`~pverosion.kernels.validation.as_triangle_mesh`, without testing
    the coordinates twice. The arrays are views of the mesh's where their
    types allow (float64 points, 64-bit ids): read them, never write them.

    Warns
    -----
    UserWarning
        As :func:`polydata_triangles`: points stored too coarsely for the
        mesh's edges.

    Raises
    ------
    InvalidMeshError
        As :func:`polydata_triangles`, or if a triangle names a point that
        does not exist.
    """
    stored, faces = _stored_triangles(mesh)
    points = as_points(stored)
    check_coordinate_precision(stored, faces)
    return points, as_faces(faces, len(points))


def replace_triangles(mesh: vtkPolyData, faces: np.ndarray) -> None:
    """Replace the polygons of ``mesh`` by the triangles ``faces`` (F, 3).

    Both cell arrays are copied: ``vtkCellArray.SetData`` keeps arrays of its
    own that share the given arrays' memory, so a NumPy buffer handed over
    without a copy would be freed with the wrapper that kept it alive while
    the cells still point into it (ParaView then crashed on the cells'
    bounds).
    """
    id_type = vtkIdTypeArray().GetDataType()
    connectivity = numpy_support.numpy_to_vtk(np.ascontiguousarray(faces, dtype=np.int64).ravel(), deep=True,
                                              array_type=id_type)
    offsets = numpy_support.numpy_to_vtk(np.arange(0, 3 * len(faces) + 1, 3, dtype=np.int64), deep=True,
                                         array_type=id_type)
    cells = vtkCellArray()
    cells.SetData(offsets, connectivity)
    mesh.SetPolys(cells)


def set_multiblock(out, blocks) -> None:
    """Fill vtkMultiBlockDataSet ``out`` with the named ``blocks`` (a pyvista.MultiBlock), in order."""
    result = vtkMultiBlockDataSet()
    result.SetNumberOfBlocks(len(blocks))
    for index, name in enumerate(blocks.keys()):
        result.SetBlock(index, blocks[name])
        result.GetMetaData(index).Set(vtkMultiBlockDataSet.NAME(), name)
    out.ShallowCopy(result)


def set_point_array(mesh, name: str, values: np.ndarray, *, copy: bool = True) -> None:
    """Add (or replace) point array ``name`` on ``mesh`` from an (N,) or (N, k) array.

    With ``copy=False`` the VTK array shares the memory of ``values`` (and keeps
    it alive): for fresh results that nothing modifies afterwards.
    """
    arr = numpy_support.numpy_to_vtk(np.ascontiguousarray(values, dtype=np.float64), deep=copy)
    arr.SetName(name)
    mesh.GetPointData().AddArray(arr)


def set_field_value(mesh, name: str, value) -> None:
    """Store a scalar, a string, or a 1-D array of numbers as field data ``name``."""
    if isinstance(value, str):
        arr = vtkStringArray()
        arr.InsertNextValue(value)
    else:
        arr = numpy_support.numpy_to_vtk(np.atleast_1d(np.asarray(value, dtype=np.float64)), deep=True)
    arr.SetName(name)
    mesh.GetFieldData().AddArray(arr)
