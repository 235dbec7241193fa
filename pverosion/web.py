"""The series viewer in a web page (trame): step slider, scalar chooser and the rendered view.

Needs the ``view`` extra (``pip install "pverosion[view]"``). The page
renders on the server (images streamed to the browser), so it works in any
browser, remote or headless, without WebGL. In Jupyter the plain
:func:`pverosion.view` plotter already shows through PyVista's trame backend.
"""

from __future__ import annotations

import socket

from pverosion.viewer import SeriesViewer

__all__ = ["build_app", "serve"]


def build_app(viewer: SeriesViewer, *, name: str = "pverosion"):
    """A trame server whose page shows ``viewer`` with a step slider and a scalar chooser.

    Parameters
    ----------
    viewer : SeriesViewer
        An off-screen viewer, best without its own widgets (``widgets=False``).
    name : str, default: "pverosion"
        Name of the trame server.

    Returns
    -------
    trame_server.Server
        Start it with ``server.start(port=..., host="127.0.0.1", open_browser=False)``.
    """
    from trame.app import get_server
    from trame.ui.vuetify3 import SinglePageLayout
    from trame.widgets import html
    from trame.widgets import vuetify3 as v3
    from trame_pyvista.widgets import PyVistaRemoteView

    server = get_server(name, client_type="vue3")
    state, ctrl = server.state, server.controller
    series = viewer.series

    def label(step: int) -> str:
        return f"step {step} / {len(series) - 1}   t = {series.times[step]:g}"

    state.step = viewer.step
    state.last_step = len(series) - 1
    state.step_label = label(viewer.step)
    state.scalars = viewer.scalars
    state.scalar_names = viewer.scalar_names

    @state.change("step")
    def _show_step(step, **_) -> None:
        step = int(step)
        if step != viewer.step:
            viewer.set_step(step)
            ctrl.view_update()
        state.step_label = label(step)

    @state.change("scalars")
    def _colour(scalars, **_) -> None:
        if scalars and scalars != viewer.scalars:
            viewer.set_scalars(scalars)
            ctrl.view_update()

    with SinglePageLayout(server) as layout:
        layout.title.set_text("pverosion")
        with layout.toolbar:
            v3.VSlider(v_model=("step",), min=0, max=("last_step",), step=1, hide_details=True,
                       classes="mx-4 step-slider", style="max-width: 50%")
            html.Span("{{ step_label }}", classes="mx-2 step-label")
            v3.VSelect(v_model=("scalars",), items=("scalar_names",), hide_details=True, density="compact",
                       style="max-width: 220px")
        with layout.content, v3.VContainer(fluid=True, classes="pa-0 fill-height"):
            view = PyVistaRemoteView(viewer, interactive_ratio=1, still_ratio=1)
            ctrl.view_update = view.update
    return server


def serve(viewer: SeriesViewer, *, host: str = "127.0.0.1", port: int = 8080, open_browser: bool = False) -> None:
    """Serve :func:`build_app`'s page at ``http://host:port/`` until interrupted; ``ValueError`` at once when the
    port is taken (before anything is built or said to be served)."""
    if port:
        with socket.socket() as probe:
            probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)  # as the server binds it
            try:
                probe.bind((host, port))
            except OSError as exc:
                raise ValueError(f"--web: port {port} on {host} is taken ({exc.strerror or exc}); give another "
                                 "port") from None
    server = build_app(viewer)
    print(f"pverosion view: serving http://{host}:{port}/", flush=True)
    server.start(host=host, port=port, open_browser=open_browser, show_connection_info=False)
