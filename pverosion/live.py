"""Live erosion: a stage steps in a background thread while a plotter shows it; picks place water or brush weathering.

:func:`interactive` returns a :class:`LiveSession`. Its solver runs one
iteration at a time in a worker thread; after an iteration it publishes a
copy of the state (with vertex normals, so the view computes nothing) if
the view has taken the previous one, and always when it stops. The
hydraulic stage also publishes the water between the fluid's substeps (on
the surface of the iteration before), so the water moves at the substep
rate. The
plotter's timer (or a script calling :meth:`LiveSession.update_view`)
moves the shown arrays to the newest copy and renders, at its own pace. Picking a point on
the surface (right click or the ``P`` key in a window, :meth:`LiveSession.pick`
or :meth:`LiveSession.pick_screen` in scripts) places the water source above
it (``stage="hydraulic"``) or adds a weathering brush there
(``stage="weather"``: only brushed regions weather).
"""

from __future__ import annotations

import os
import threading
from pathlib import Path

import numba
import numpy as np
import pyvista as pv

from pverosion.filters.hydraulic import particles_polydata
from pverosion.filters.mesh_solver import evolving_surface
from pverosion.io import write_atomic
from pverosion.kernels.fluid.particle_fluid import Emitter, FluidParameters
from pverosion.kernels.hydraulic.erosion import HydraulicSolver
from pverosion.kernels.mesh.geometry import average_edge_length, vertex_normals
from pverosion.kernels.validation import as_triangle_mesh
from pverosion.kernels.weathering.model import WeatheringSolver
from pverosion.plotting import _offscreen_pyvista, scalar_style

__all__ = ["STAGES", "LiveSession", "interactive"]


class _Halt(Exception):
    """Raised after an iteration to leave the solver's run() when the live view pauses."""

STAGES = ("hydraulic", "weather")
"""Stages that run live."""

TIMER_MS = 50
"""Period of a window's view updates in milliseconds (a late one starts as soon as the last returns)."""


class LiveSession:
    """An erosion stage stepping in the background, shown in a plotter.

    Parameters
    ----------
    mesh : pyvista.PolyData
        Closed triangle surface; it is not modified.
    stage : {"hydraulic", "weather"}
    plotter : pyvista.Plotter, optional
        Plotter to draw into (default: a new one).
    radius : float, default: 0.0
        Hydraulic: particle radius (0: half the average edge length).
    source_radius : float, optional
        Hydraulic: radius of the water source's disc (default: 3 particle diameters).
        Weather: radius of a brush (default: 10 % of the bounding box diagonal).
    speed : float, optional
        Hydraulic: speed of the released water (default: a layer of particles every second iteration).
    gravity : (3,) float, default: (0, 0, -9.81)
        Hydraulic: gravity in model units per second squared; the source hangs above a pick against it
        (e.g. ``(0, -9.81, 0)`` for the bunny scan, whose up is +y).
    threads : int, optional
        Threads the worker's compiled kernels use (default: all of numba's but one, at least one),
        so that rendering keeps a core.
    **options
        Passed to :class:`~pverosion.kernels.hydraulic.erosion.HydraulicSolver` or
        :class:`~pverosion.kernels.weathering.model.WeatheringSolver`.

    Attributes
    ----------
    solver : HydraulicSolver or WeatheringSolver
    plotter : pyvista.Plotter
    mesh : pyvista.PolyData
        What the view shows: the current surface with ``erosion_depth`` and
        ``input_id`` (index of each vertex in the input mesh).
    particles : pyvista.PolyData
        The water particles shown (hydraulic).
    source : numpy.ndarray, shape (3,) or None
        Centre of the water source's disc (hydraulic).
    brushes : list of numpy.ndarray
        Centres of the weathering brushes (weather).
    updates : int
        View updates that showed a new state.
    shown_step : int
        Iteration the view shows.
    shown_time : float
        Simulated time the view shows, in iterations: ``shown_step``, plus the
        fraction of the next iteration's fluid substeps done when the view
        shows the water between substeps.
    """

    def __init__(self, mesh: pv.PolyData, *, stage: str = "hydraulic", plotter: pv.Plotter | None = None,
                 radius: float = 0.0, source_radius: float | None = None, speed: float | None = None,
                 gravity=(0.0, 0.0, -9.81), threads: int | None = None, **options) -> None:
        if stage not in STAGES:
            raise ValueError(f"stage must be one of {STAGES}; got {stage!r}")
        available = numba.config.NUMBA_NUM_THREADS
        if threads is None:
            threads = max(available - 1, 1)
        if not 1 <= threads <= available:
            raise ValueError(f"threads must be in [1, {available}]; got {threads!r}")
        self.threads = int(threads)
        points, faces, _ = evolving_surface(mesh)  # the checks of the stage's filter
        points, faces = as_triangle_mesh(np.asarray(points, dtype=np.float64), faces)
        self.stage = stage
        self._input = (points, faces)
        self._options = options
        e_avg = average_edge_length(points, faces)
        self.radius = float(radius) if radius > 0 else 0.5 * e_avg
        diagonal = float(np.linalg.norm(points.max(axis=0) - points.min(axis=0)))
        if source_radius is None:
            source_radius = 6.0 * self.radius if stage == "hydraulic" else 0.1 * diagonal
        if not source_radius > 0:
            raise ValueError(f"source_radius must be > 0; got {source_radius!r}")
        self.source_radius = float(source_radius)
        self._speed = speed
        self._fluid = FluidParameters(radius=self.radius, gravity=tuple(gravity))
        self._lock = threading.Lock()  # held while the solver steps
        self._wake = threading.Condition(self._lock)
        self._picks_lock = threading.Lock()
        self._picks: list[np.ndarray] = []
        self._callbacks: list = []
        self._thread: threading.Thread | None = None
        self._stop = False
        self._halt = False
        self.paused = True
        self.error: BaseException | None = None
        self.updates = 0
        self.shown_step = 0
        self.shown_time = 0.0
        self.plotter = plotter if plotter is not None else pv.Plotter()
        self.mesh = pv.PolyData()
        self.particles = pv.PolyData()
        self._actor = None
        self._text = None
        self._faces: np.ndarray | None = None
        self._drawn: tuple | None = (None, 0)
        self._build()
        self._publish()
        self._draw()

    # -- simulation (worker thread) ----------------------------------------------------------

    def _build(self) -> None:
        points, faces = self._input
        self.source: np.ndarray | None = None
        self.brushes: list[np.ndarray] = []
        self._travel = 0.0
        self._primed = False
        if self.stage == "hydraulic":
            self.solver = HydraulicSolver(points, faces, fluid=self._fluid, **self._options)
            self._gravity = np.asarray(self.solver.fluid.params.gravity, dtype=np.float64)
            self._layer = Emitter(position=(0.0, 0.0, 0.0), direction=tuple(self._gravity),
                                  radius=self.source_radius, rate=1.0).lattice(2.0 * self.radius)
            self.solver.fluid.on_substep = self._between_substeps
        else:
            self.solver = WeatheringSolver(points, faces, erodibility=self._brushed, **self._options)
        self._version = 0
        self._shown = -1
        self._stale = False

    def _brushed(self, points: np.ndarray) -> np.ndarray:
        """Erodibility of ``points`` (N, 3): 1 within a brush's radius, 0 elsewhere."""
        out = np.zeros(len(points))
        for centre in self.brushes:
            out[np.linalg.norm(points - centre, axis=1) <= self.source_radius] = 1.0
        return out

    def _pour(self) -> None:
        """Release a layer of particles from the source whenever the stream has advanced one diameter."""
        if self.source is None:
            return
        fluid = self.solver.fluid
        spacing = 2.0 * self.radius
        speed = self._speed if self._speed is not None else spacing / (2.0 * fluid.dt)
        self._travel += speed * fluid.dt
        if self._travel < spacing:
            return
        self._travel -= spacing
        down = self._gravity / np.linalg.norm(self._gravity)
        room = fluid.params.max_particles - len(fluid.positions)
        layer = (self.source + self._layer)[:max(room, 0)]
        if len(layer):
            fluid.add_particles(layer, np.broadcast_to(speed * down, layer.shape))

    def _apply_picks(self) -> None:
        """Move the source / add the brushes picked since the last iteration (the solver is not stepping)."""
        with self._picks_lock:
            picks, self._picks = self._picks, []
        for point in picks:
            if self.stage == "hydraulic":
                up = -self._gravity / np.linalg.norm(self._gravity)
                self.source = point + 8.0 * self.radius * up
                self._travel = 2.0 * self.radius  # release the first layer at the next iteration
            else:
                self.brushes.append(point)

    def _before_steps(self) -> None:
        self._apply_picks()
        if not self._primed and self.stage == "hydraulic":
            self._pour()
        self._primed = True

    def _after_step(self, solver) -> None:
        """After every accepted iteration: take the picks, pour, publish the state; leave run() when asked to."""
        self._apply_picks()
        if self.stage == "hydraulic":
            self._pour()
        if self._state[0] == self._shown:  # the view has taken the last state: hand it the next
            self._publish()
        else:
            self._stale = True
        for callback in self._callbacks:
            callback(solver.step_count)
        if self._halt:
            raise _Halt

    def step(self, iterations: int = 1) -> None:
        """Run ``iterations`` iterations now, in the calling thread (while the worker is paused)."""
        with self._lock:
            self._before_steps()
            try:
                self.solver.run(int(iterations), on_step=self._after_step)
            finally:
                self._flush()

    def _publish(self, cloud: pv.PolyData | None = None, time: float | None = None) -> None:
        """Copy the state the view needs, with the vertex normals for smooth shading, and swap it in whole.

        ``cloud`` and ``time`` (in iterations) give the water between two substeps; the surface is then the
        last iteration's, copied again only if the view had not shown it.
        """
        s = self.solver
        if cloud is None:
            cloud = particles_polydata(s) if self.stage == "hydraulic" else pv.PolyData()
        self._version += 1
        if time is not None and not self._stale:  # the surface shown is current: only the water is new
            self._state = (self._version, *self._state[1:5], cloud, s.step_count, self._state[7], time)
            return
        normals = vertex_normals(s.points, s.faces)  # here, not in the view's pipeline: the render thread only draws
        self._state = (self._version, s.points.copy(), s.faces.copy(), s.erosion_depth(), s.ids.copy(), cloud,
                       s.step_count, normals, float(s.step_count) if time is None else time)
        self._stale = False

    def _between_substeps(self, done: int, positions: np.ndarray, velocities: np.ndarray, ids: np.ndarray) -> None:
        """The fluid's substep hook: hand the view the water if it has taken the last state."""
        if self._state[0] != self._shown:
            return
        cloud = pv.PolyData(positions.copy())
        cloud["velocity"] = velocities.copy()
        cloud["speed"] = np.linalg.norm(velocities, axis=1)
        cloud["particle_id"] = ids
        self._publish(cloud, self.solver.step_count + done / self.solver.fluid.params.substeps)

    def _flush(self) -> None:
        """Publish the last iteration if the view had not taken the one before when it ended."""
        if self._stale:
            self._publish()

    def _work(self) -> None:
        numba.set_num_threads(self.threads)  # per thread: the caller's kernels keep their setting
        try:
            while True:
                with self._lock:
                    while self.paused and not self._stop:
                        self._wake.wait()
                    if self._stop:
                        return
                    self._before_steps()
                    try:
                        # one at a time: run() has the guard check its last step, so every state shown is checked
                        # and a rollback redoes one iteration, not the guard's whole period
                        self.solver.run(1, on_step=self._after_step)
                    except _Halt:
                        pass
                    finally:
                        self._flush()
        except BaseException as exc:  # shown by update_view and re-raised by stop()
            self.error = exc
            self.paused = True

    def on_step(self, callback) -> None:
        """Call ``callback(step)`` after every iteration, in the thread that runs it."""
        self._callbacks.append(callback)

    def start(self) -> None:
        """Start (or resume) stepping in the background."""
        self._halt = False
        with self._lock:
            self.paused = False
            self._stop = False
            self._wake.notify_all()
        if self._thread is None or not self._thread.is_alive():
            self._thread = threading.Thread(target=self._work, name="pverosion-live", daemon=True)
            self._thread.start()

    def pause(self) -> None:
        """Stop stepping after the current iteration; returns once the worker has stopped."""
        self.paused = True
        self._halt = True
        with self._lock:  # the worker holds it while it steps
            pass

    def stop(self) -> None:
        """End the worker thread; re-raise what made it fail, if anything."""
        self._stop = True
        self.pause()
        with self._lock:
            self._wake.notify_all()
        if self._thread is not None:
            self._thread.join()
            self._thread = None
        if self.error is not None:
            raise self.error

    def reset(self) -> None:
        """Back to the input mesh, without water or brushes; a running live view goes on running."""
        running = not self.paused
        self.pause()
        with self._lock:
            self._build()
            self._publish()
        with self._picks_lock:
            self._picks = []
        self.update_view()
        if running:
            self.start()

    @property
    def steps(self) -> int:
        """Iterations done since the start or the last reset."""
        return int(self.solver.step_count)

    # -- interaction -------------------------------------------------------------------------

    def pick(self, point) -> None:
        """Place the water source above ``point`` (hydraulic) or add a weathering brush at it (weather).

        Taken before the next iteration (at once when the solver is not stepping).
        """
        point = np.asarray(point, dtype=np.float64).reshape(3)
        with self._picks_lock:
            self._picks.append(point)
        if self._lock.acquire(blocking=False):
            try:
                self._apply_picks()
            finally:
                self._lock.release()

    def pick_screen(self, x: float, y: float) -> np.ndarray | None:
        """Pick the surface at display pixel (x, y) as a click does; return the point (None: missed)."""
        from vtkmodules.vtkRenderingCore import vtkCellPicker

        picker = vtkCellPicker()
        picker.SetTolerance(1e-4)
        picker.PickFromListOn()
        picker.AddPickList(self._actor)
        if not picker.Pick(float(x), float(y), 0.0, self.plotter.renderer):
            return None
        point = np.array(picker.GetPickPosition())
        self.pick(point)
        return point

    def save(self, path: str | os.PathLike) -> Path:
        """Write what the view shows: the surface (``.vtp``) or surface and particles (``.vtm``)."""
        path = Path(path)
        self.update_view(render=False)
        if path.suffix == ".vtm":
            return write_atomic(pv.MultiBlock({"mesh": self.mesh.copy(), "particles": self.particles.copy()}), path)
        return write_atomic(self.mesh.copy(), path)

    # -- view --------------------------------------------------------------------------------

    def update_view(self, *, render: bool = True) -> bool:
        """Show the newest published state; return whether it was new."""
        state = self._state  # replaced whole by the worker, never changed
        if state[0] == self._shown:
            return False
        version, points, faces, depth, ids, cloud, step, normals, time = state
        self._shown = version
        self.shown_step = int(step)
        self.shown_time = time
        if self._faces is not None and np.array_equal(self._faces, faces):
            self.mesh.points = points  # same triangles: move the points only
        else:
            self.mesh.shallow_copy(pv.PolyData.from_regular_faces(points, faces))
            self._faces = faces
        self.mesh.point_data["erosion_depth"] = depth
        self.mesh.point_data["input_id"] = ids
        self.mesh.point_data.set_array(normals, "Normals")
        self.mesh.point_data.active_normals_name = "Normals"
        self.particles.shallow_copy(cloud)
        if self._actor is not None:
            self._actor.mapper.scalar_range = scalar_style("erosion_depth", np.append(depth, 0.0))["clim"]
        if self._text is None:
            self._text = self.plotter.add_text("", position="upper_left", font_size=10, name="live_label")
        self._text.SetText(2, self._label(step))  # a new text actor would render the scene once more
        self._draw_source()
        self.updates += 1
        if render:
            self.plotter.render()
        return True

    def _label(self, step: int) -> str:
        state = "error: " + str(self.error) if self.error else "paused" if self.paused else "running"
        what = "right-click: water source" if self.stage == "hydraulic" else "right-click: weathering brush"
        return f"{self.stage}  iteration {step}  ({state})   {what}"

    def _draw(self) -> None:
        p = self.plotter
        self.update_view(render=False)
        style = scalar_style("erosion_depth", np.append(self.mesh["erosion_depth"], 0.0))
        self._actor = p.add_mesh(self.mesh, scalars="erosion_depth", interpolation="gouraud", name="live_mesh",
                                 scalar_bar_args={"title": "erosion_depth"}, **style)
        if self.stage == "hydraulic":
            self.particles.shallow_copy(pv.PolyData(np.zeros((1, 3))))  # an actor needs a point to start
            p.add_mesh(self.particles, color="#2f6fd6", render_points_as_spheres=True,
                       point_size=4, name="live_particles")
            self._shown = -1
            self.update_view(render=False)
        if p.iren is not None and not p.off_screen:
            p.enable_surface_point_picking(callback=self.pick, show_point=False, left_clicking=False,
                                           show_message=False)
            p.add_checkbox_button_widget(lambda on: self.start() if on else self.pause(), value=not self.paused,
                                         position=(10.0, 10.0), size=30)
            p.add_text("run", position=(45, 15), font_size=9, name="run_label")
            p.add_checkbox_button_widget(lambda _: self.reset(), position=(10.0, 50.0), size=30, color_on="grey")
            p.add_text("reset", position=(45, 55), font_size=9, name="reset_label")
            p.add_checkbox_button_widget(lambda _: print(f"saved -> {self.save(self._save_name())}"),
                                         position=(10.0, 90.0), size=30, color_on="grey")
            p.add_text("save", position=(45, 95), font_size=9, name="save_label")
            p.iren.add_observer("TimerEvent", lambda *_: self.update_view())
            p.iren.create_timer(TIMER_MS, repeating=True)
        p.view_isometric()

    def _save_name(self) -> str:
        return f"live_{self.stage}_{self.steps:05d}.{'vtm' if self.stage == 'hydraulic' else 'vtp'}"

    def _draw_source(self) -> None:
        """Show the water source's disc or the brushes when they changed."""
        key = (None if self.source is None else tuple(self.source), len(self.brushes))
        if key == self._drawn:
            return
        self._drawn = key
        if self.stage == "hydraulic" and self.source is not None:
            disc = pv.Disc(center=self.source, inner=0.0, outer=self.source_radius, normal=-self._gravity, c_res=24)
            self.plotter.add_mesh(disc, color="#2f6fd6", opacity=0.5, name="live_source", reset_camera=False)
        elif self.brushes:
            spheres = pv.MultiBlock([pv.Sphere(radius=self.source_radius, center=c) for c in self.brushes])
            self.plotter.add_mesh(spheres.combine(), color="orange", style="wireframe", opacity=0.3,
                                  name="live_source", reset_camera=False)
        else:
            self.plotter.remove_actor("live_source", render=False)


def interactive(mesh: pv.PolyData, *, stage: str = "hydraulic", off_screen: bool | None = None,
                window_size: tuple[int, int] = (1024, 768), multi_samples: int = 0, **options) -> LiveSession:
    """Erode ``mesh`` live: pick on the surface to pour water or brush weathering, watch it change.

    Parameters
    ----------
    mesh : pyvista.PolyData
        Closed triangle surface (outward faces); it is not modified.
    stage : {"hydraulic", "weather"}, default: "hydraulic"
    off_screen : bool, optional
        Render without a window (default: PyVista's setting).
    window_size : tuple of int, default: (1024, 768)
    multi_samples : int, default: 0
        Samples per pixel of the render window's anti-aliasing; each sample multiplies the cost of
        a software (llvmpipe) render, so the live view renders one. The scene is lit by one
        headlight (PyVista's default light kit has five).
    **options
        See :class:`LiveSession`.

    Returns
    -------
    LiveSession
        Call ``.start()`` and ``.plotter.show()``; ``.pause()``, ``.reset()``,
        ``.save(path)`` and ``.stop()`` work from scripts too.
    """
    if off_screen or (off_screen is None and pv.OFF_SCREEN):
        _offscreen_pyvista()
        off_screen = True
    plotter = pv.Plotter(off_screen=off_screen, window_size=list(window_size), lighting="none")
    plotter.add_light(pv.Light(light_type="headlight"))  # one light: a software render shades per light
    plotter.ren_win.SetMultiSamples(int(multi_samples))
    return LiveSession(mesh, stage=stage, plotter=plotter, **options)
