"""What a tab shows of a built scene, without rebuilding it: layers on or off, one view highlighted.

A layer is one group node; hiding it hides everything under it (viser hides a
node's children with it), so a layer and the Surfaces choice (``field.set_component``,
on the nodes under ``/field``) never undo each other.
"""
from __future__ import annotations

from typing import Any

# the panel's checkbox → the node it shows and hides
LAYERS = {
    "Boards": "/boards",
    "Residual vectors": "/residuals",
    "Knot grid": "/image_plane/knots",
    "Field surfaces": "/field",
}


def present(handles: dict[str, Any]) -> list[str]:
    """The layers this scene has (no Knot grid when the model has no field)."""
    return [name for name, path in LAYERS.items() if path in handles]


def set_layers(handles: dict[str, Any], shown: dict[str, bool]) -> None:
    """Show the layers ``shown`` marks True (a layer it does not name stays as it is)."""
    for name, on in shown.items():
        path = LAYERS.get(name)
        if path in handles:
            handles[path].visible = on


def highlight(handles: dict[str, Any], views: list[str], view: str | None) -> None:
    """Show the bright edge on the board of ``view`` (a view name) alone; None: on none."""
    for i, name in enumerate(views):
        edge = handles.get(f"/boards/{i}/highlight")
        if edge is not None:
            edge.visible = name == view
