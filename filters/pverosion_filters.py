"""ParaView plugin: every pverosion stage as a filter (Filters > pverosion).

Load it in ParaView with Tools > Manage Plugins > Load New, with pverosion
installed in ParaView's Python. The proxies are generated from the filters'
own option metadata (pverosion.filters.paraview), so this file never changes
when a stage is added.
"""

from types import SimpleNamespace

from paraview.util.vtkAlgorithm import smdomain, smhint, smproperty, smproxy

from pverosion.filters import ALL_FILTERS
from pverosion.filters.paraview import make_proxy

_DECORATORS = SimpleNamespace(smproxy=smproxy, smproperty=smproperty, smdomain=smdomain, smhint=smhint)

for _filter_cls in ALL_FILTERS:
    _proxy = make_proxy(_filter_cls, _DECORATORS, __name__)
    globals()[_proxy.__name__] = _proxy
