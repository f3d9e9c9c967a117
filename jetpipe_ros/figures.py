"""Figures for the HTML reports: matplotlib without a display, and a figure as an inline PNG."""

from __future__ import annotations

import base64
import io
from typing import Any


def pyplot() -> Any:
    """``matplotlib.pyplot`` on the Agg backend (no display needed), imported on first use."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def png_img(fig: Any, dpi: int = 90) -> str:
    """A matplotlib figure as an inline ``<img>`` (PNG, base64, ``dpi`` dots per inch), as wide
    as the page at most (scaled down in a narrower window, never cut), the figure closed."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi, bbox_inches="tight")
    pyplot().close(fig)
    return ("<img alt='figure' style='max-width:100%' src='data:image/png;base64,"
            + base64.b64encode(buf.getvalue()).decode() + "'>")
