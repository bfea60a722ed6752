"""Loads the ACTOPO plugin (actopo_plugin.py beside this file) into ParaView.

    View > Python Shell > Run Script, this file               # the GUI
    ACTOPO_PARAVIEW_PLUGIN=/path/to/paraview/actopo_plugin.py \
        paraview --script=/path/to/paraview/load_actopo.py    # the GUI, at start-up
    runpy.run_path("/path/to/paraview/load_actopo.py")       # pvbatch, pvpython scripts

It first applies the fix ParaView 5.11.0 needs to load any Python plugin under Python 3.11
(Debian 12): its plugin loader imports inspect.getargspec, which Python 3.11 removed. With
ParaView >= 5.11.1 or Python <= 3.10 it changes nothing, and Tools > Manage Plugins > Load New
works on actopo_plugin.py directly. The filters then appear under Filters > ACTOPO, and in
paraview.simple (ACTOPOCriticalPoints, ACTOPODiscreteGradient, ACTOPOMorseSmaleComplex).
"""

import inspect
import os

# Before LoadPlugin: ParaView's loader imports paraview.detail.pythonalgorithm first.
if not hasattr(inspect, "getargspec"):
    inspect.getargspec = inspect.getfullargspec  # type: ignore[attr-defined]

from paraview import simple


def plugin_path() -> str:
    """$ACTOPO_PARAVIEW_PLUGIN, else actopo_plugin.py beside this script. pvbatch, pvpython and
    the Python Shell's Run Script define __file__; `paraview --script` does not."""
    configured = os.environ.get("ACTOPO_PARAVIEW_PLUGIN")
    if configured:
        return configured
    try:
        here = os.path.dirname(os.path.abspath(__file__))
    except NameError:
        raise RuntimeError(
            "load_actopo.py cannot tell where it is (paraview --script runs it without "
            "__file__): set ACTOPO_PARAVIEW_PLUGIN=/path/to/paraview/actopo_plugin.py, or use "
            "View > Python Shell > Run Script") from None
    return os.path.join(here, "actopo_plugin.py")


simple.LoadPlugin(plugin_path())
