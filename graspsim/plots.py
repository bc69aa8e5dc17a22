"""Figures: graspability maps as 3-D scatters coloured by grade (paper figs. 5 and 7).

matplotlib is used with the Agg backend (files only, no screen needed).
"""

from __future__ import annotations

import os

import numpy as np

from graspsim.maps.graspmap import GraspabilityMap

__all__ = ["PLOT_POINTS", "plot_map", "plot_maps", "plot_clouds", "map_figure", "image_format", "plot_design",
           "pyplot"]

#: The most grasps a map plot draws (a uniform sample of the rest; the plot says so).
PLOT_POINTS = 30000

_FORMATS = ("png", "pdf", "svg", "jpg", "jpeg", "tif", "tiff", "webp", "eps", "ps")


def image_format(path: str | os.PathLike) -> str:
    """The image format named by ``path``'s extension (``png`` when it has none); an
    extension matplotlib cannot write raises :class:`InvalidParameterError` (say it before
    the work, not after)."""
    from pathlib import Path

    ext = Path(path).suffix.lower().lstrip(".")
    if not ext:
        return "png"
    if ext not in _FORMATS:
        from graspsim.errors import InvalidParameterError

        raise InvalidParameterError(f"cannot write an image to {path}: unknown extension .{ext} "
                                    f"(valid: {', '.join('.' + f for f in _FORMATS)})")
    return ext


def pyplot():
    """matplotlib.pyplot on the headless Agg backend (imported on first use: matplotlib is
    heavy and only figures need it)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


#: what one dot of a map plot is, by ``what``
_DOT = {"grasp_point": "a grasp's grasp point (midway between its contacts)", "wrist": "a grasp's wrist position"}


def _draw(ax, gmap: GraspabilityMap, what: str, max_points: int, min_grade: float, title: str):
    """One map on ``ax``; returns the scatter and the note of what was drawn."""
    from matplotlib.ticker import FuncFormatter, MaxNLocator

    from graspsim.primitives import shape_from_dict

    sel = np.flatnonzero(gmap.above(min_grade))
    shown = len(sel)
    if len(sel) > max_points:  # a uniform sample, deterministic (drawn best last: on top)
        sel = np.sort(np.random.default_rng(0).choice(sel, max_points, replace=False))
    pts = (gmap.grasp_point if what == "grasp_point" else gmap.wrist_position)[sel]
    g = gmap.grade[sel]
    order = np.argsort(g)
    sc = ax.scatter(*pts[order].T, c=g[order], cmap="viridis", vmin=0.0, vmax=1.0, s=2, depthshade=False)
    extent = [pts] if len(pts) else []
    try:
        mesh = shape_from_dict(gmap.meta.object).mesh(sections=32)
        ax.plot_trisurf(*mesh.vertices.T, triangles=mesh.faces, color=(0.7, 0.7, 0.7, 0.25),
                        edgecolor="none")
        extent.append(mesh.vertices)  # the axes hold the whole object, whatever is drawn
    except Exception:  # noqa: BLE001 - a mesh-referenced object: draw the grasps only
        pass
    allp = np.concatenate(extent) if extent else np.zeros((1, 3))
    c = 0.5 * (allp.max(0) + allp.min(0))
    r = 0.5 * float(np.max(allp.max(0) - allp.min(0))) * 1.05 or 0.05
    ax.set_xlim(c[0] - r, c[0] + r)
    ax.set_ylim(c[1] - r, c[1] + r)
    ax.set_zlim(c[2] - r, c[2] + r)
    cm = FuncFormatter(lambda v, _: f"{100 * v:.3g}")
    for axis in (ax.xaxis, ax.yaxis, ax.zaxis):
        axis.set_major_locator(MaxNLocator(4))  # few ticks: no labels run into each other
        axis.set_major_formatter(cm)
    ax.tick_params(labelsize=7, pad=1)
    ax.set_xlabel("x [cm]", labelpad=2)
    ax.set_ylabel("y [cm]", labelpad=2)
    ax.set_zlabel("z [cm]", labelpad=2)
    ax.set_box_aspect(None, zoom=0.82)  # room inside the axes for the z label
    among = f"grasps with grade > {min_grade:g}" if min_grade > 0 else "grasps"
    drawn = (f"all {shown:,} {among} drawn" if len(sel) == shown
             else f"a uniform sample of {len(sel):,} of the {shown:,} {among} drawn")
    ax.set_title(f"{title}\n{drawn}", fontsize=8)
    return sc


def plot_map(gmap: GraspabilityMap, path: str | os.PathLike, *, what: str = "grasp_point",
             min_grade: float = 0.0, max_points: int = PLOT_POINTS, title: str | None = None,
             format: str | None = None) -> None:
    """Save a 3-D scatter of grasp points (or ``what="wrist"`` positions) coloured by
    grade, over a translucent mesh of the object."""
    plot_maps([gmap], path, what=what, min_grade=min_grade, max_points=max_points,
              titles=[title] if title else None, format=format)


def plot_maps(maps: list[GraspabilityMap], path: str | os.PathLike, *, what: str = "grasp_point",
              min_grade: float = 0.0, max_points: int = PLOT_POINTS, titles: list[str] | None = None,
              format: str | None = None) -> None:
    """Several maps side by side with one colour bar (e.g. FS vs adapted, paper fig. 5).

    The file is written atomically; ``format`` defaults to :func:`image_format` of
    ``path`` (give it when ``path`` is a temporary name)."""
    from graspsim._atomic import atomic_path
    from graspsim.errors import OutputPathError

    format = format or image_format(path)
    fig = map_figure(maps, what=what, min_grade=min_grade, max_points=max_points, titles=titles)
    try:
        with atomic_path(path, OutputPathError) as tmp:
            fig.savefig(tmp, dpi=130, format=format)
    finally:
        pyplot().close(fig)


def map_figure(maps: list[GraspabilityMap], *, what: str = "grasp_point", min_grade: float = 0.0,
               max_points: int = PLOT_POINTS, titles: list[str] | None = None):
    """The matplotlib figure :func:`plot_maps` saves (the caller closes it)."""
    if what not in ("grasp_point", "wrist"):
        from graspsim.errors import InvalidParameterError

        raise InvalidParameterError(f"what must be 'grasp_point' or 'wrist', got {what!r}")
    plt = pyplot()
    fig = plt.figure(figsize=(4.5 * len(maps) + 1, 4.5))
    sc = None
    for i, m in enumerate(maps):
        ax = fig.add_subplot(1, len(maps), i + 1, projection="3d")
        obj = m.meta.object
        default = f"{obj.get('primitive', 'object')}: {len(m)} grasps, {int(m.accepted.sum())} > {m.threshold:g}"
        sc = _draw(ax, m, what, max_points, min_grade, titles[i] if titles else default)
    fig.colorbar(sc, ax=fig.axes, shrink=0.6, pad=0.06, label="grade")
    fig.text(0.5, 0.03, f"each dot: {_DOT[what]}, coloured by its grade; grey: the object", fontsize=7,
             ha="center")
    return fig


def plot_clouds(clouds: dict[str, np.ndarray], path: str | os.PathLike, rng: np.random.Generator, *,
                max_points: int = 8000) -> None:
    """Point clouds side by side (3-D scatter, equal axes, coloured by z): ``clouds``
    maps a title to (N, 3) points [m]; at most ``max_points`` drawn from each by ``rng``."""
    from graspsim._atomic import atomic_path
    from graspsim.errors import OutputPathError

    fmt = image_format(path)
    plt = pyplot()
    fig = plt.figure(figsize=(3.6 * len(clouds), 3.8))
    for i, (name, pts) in enumerate(clouds.items()):
        ax = fig.add_subplot(1, len(clouds), i + 1, projection="3d")
        p = pts[rng.permutation(len(pts))[:max_points]]
        ax.scatter(*p.T, s=0.5, c=p[:, 2], cmap="copper")
        c, r = 0.5 * (p.max(0) + p.min(0)), 0.5 * float(np.max(np.ptp(p, axis=0)))
        ax.set(xlim=(c[0] - r, c[0] + r), ylim=(c[1] - r, c[1] + r), zlim=(c[2] - r, c[2] + r))
        ax.set_title(f"{name}: {len(pts)} points", fontsize=9)
        ax.set_axis_off()
    fig.tight_layout()
    try:
        with atomic_path(path, OutputPathError) as tmp:
            fig.savefig(tmp, dpi=120, format=fmt)
    finally:
        plt.close(fig)


#: design-sweep panels: (row key, axis label), every value in percent
DESIGN_METRICS = (("VR", "VR of grasps > 0.7 [%]"), ("SR", "SR of grasps > 0.7 [%]"),
                  ("share_accepted", "grasps > 0.7 [% of collision-free]"),
                  ("success", "lift-and-place success [% of feasible]"))


def _design_series(rows: list[dict], obj: str, key: str) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """x [mm], mean, min, max over the sizes of ``obj`` (rows with ``kind``, ``value``)."""
    xs = sorted({r["value"] for r in rows if r["kind"] == obj})
    mean, lo, hi = [], [], []
    for x in xs:
        if key == "success":  # pooled over the sizes: successes / feasible trials
            sims = [r["sim"] for r in rows if r["kind"] == obj and r["value"] == x and "sim" in r]
            f = sum(s["feasible"] for s in sims)
            v = [100.0 * sum(s["success"] for s in sims) / f] if f else [np.nan]
        else:
            v = [100.0 * r[key] for r in rows if r["kind"] == obj and r["value"] == x and key in r]
        mean.append(np.mean(v) if v else np.nan)
        lo.append(np.min(v) if v else np.nan)
        hi.append(np.max(v) if v else np.nan)
    return 1000 * np.asarray(xs), np.asarray(mean), np.asarray(lo), np.asarray(hi)


def plot_design(rows: list[dict], path: str | os.PathLike, *, param: str, base_value: float | None = None,
                title: str | None = None) -> None:
    """A design sweep (rows of :func:`graspsim.apps.design.sweep` with ``kind`` set to the
    primitive): one panel per metric against the parameter [mm], a line per primitive
    (mean over its sizes, band from the smallest to the largest; success pooled over
    the sizes), the base gripper's value marked. Written atomically."""
    from graspsim._atomic import atomic_path
    from graspsim.errors import OutputPathError

    plt = pyplot()
    kinds = list(dict.fromkeys(r["kind"] for r in rows))
    fig, axes = plt.subplots(1, len(DESIGN_METRICS), figsize=(4.2 * len(DESIGN_METRICS), 3.8))
    for ax, (key, label) in zip(axes, DESIGN_METRICS):
        for i, k in enumerate(kinds):
            x, m, lo, hi = _design_series(rows, k, key)
            ax.plot(x, m, marker="o", color=f"C{i}", label=k.replace("_", " "))
            if key != "success":
                ax.fill_between(x, lo, hi, color=f"C{i}", alpha=0.12, linewidth=0)
        if base_value is not None:
            ax.axvline(1000 * base_value, color="0.5", linestyle=":", linewidth=1)
        if key == "success":
            ax.set_ylim(0, 103)  # a rate: not zoomed onto a few points' spread
        ax.set_xlabel(f"{param.replace('_', ' ')} [mm]")
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8)
    if title:
        fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    try:
        with atomic_path(path, OutputPathError) as tmp:
            fig.savefig(tmp, dpi=110, format=image_format(path))
    finally:
        plt.close(fig)
