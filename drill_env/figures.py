"""Figures for files, drawn without pyplot.

Every picture drill-env writes (benchmark charts, learning curves, maps, charts of modes
and wells, the demo's) is a matplotlib ``Figure`` on the Agg canvas made here. pyplot
would have had to be switched to Agg first, which in a notebook switched off the inline
plots for the rest of the session; a ``Figure`` of its own leaves the process's backend
as it is and is not kept open in pyplot's list of figures (nothing to close).
"""

from __future__ import annotations

from typing import Any


def agg_figure(**kwargs: Any) -> Any:
    """A ``matplotlib.figure.Figure(**kwargs)`` on an Agg canvas (``fig.canvas`` can
    measure text, ``fig.savefig`` writes PNGs), without pyplot."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(**kwargs)
    FigureCanvasAgg(fig)
    return fig
