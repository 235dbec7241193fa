"""ParaView plugin: every pverosion stage as a filter (Filters > pverosion).

Set pverosion up for ParaView's Python with ``pverosion paraview setup
--pvpython /path/to/pvpython`` (see docs/topics/paraview.md), then load this
file with Tools > Manage Plugins > Load New, or put its folder
(``pverosion paraview plugin-path``) on ``PV_PLUGIN_PATH``. The proxies are
generated from the filters' own option metadata (pverosion.filters.paraview),
so this file never changes when a stage is added.

Loading also registers the curvature colour-map preset (Presets dialog,
``pverosion_curvature``) and makes it the default colour map of
``mean_curvature``.
"""

from pathlib import Path
from types import SimpleNamespace

from paraview.modules.vtkRemotingServerManager import vtkSMSettings
from paraview.modules.vtkRemotingViews import vtkSMTransferFunctionPresets
from paraview.util.vtkAlgorithm import smdomain, smhint, smproperty, smproxy

from pverosion.filters import ALL_FILTERS
from pverosion.filters.paraview import curvature_settings, make_proxy
from pverosion.plotting import CURVATURE_CMAP

_DECORATORS = SimpleNamespace(smproxy=smproxy, smproperty=smproperty, smdomain=smdomain, smhint=smhint)

for _filter_cls in ALL_FILTERS:
    _proxy = make_proxy(_filter_cls, _DECORATORS, __name__)
    globals()[_proxy.__name__] = _proxy

_presets = vtkSMTransferFunctionPresets.GetInstance()
if not _presets.HasPreset(CURVATURE_CMAP):
    _presets.ImportPresets(str(Path(__file__).with_name("pverosion_curvature.json")))
vtkSMSettings.GetInstance().AddCollectionFromString(curvature_settings(), 0.0)
