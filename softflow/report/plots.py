"""Every figure of the notebooks: one function per figure type, data in, Figure out.

Lengths arrive in SI units and are drawn in mm. Every function draws under ``STYLE`` and takes
its colours from ``PALETTE``, so a model has the same colour in every figure.
"""

from __future__ import annotations

import functools

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.colors import LogNorm
from matplotlib.lines import Line2D
from matplotlib.ticker import FuncFormatter, NullLocator

from softflow.report.tables import LABELS
from softflow.studies.study import FLOOR

MM = 1e3  # m -> mm for axes

# One colour per series, in every figure. Models (and the floor) never share a figure with
# reference families or twin configurations, so those two groups may reuse nearby hues.
PALETTE = {
    "mlp": "#1f77b4",
    "mlp-physical": "#6baed6",  # the MLP's hue, lighter: the same regression with RF-Physical's prior
    "lstm": "#9467bd",
    "transformer": "#8c564b",
    "rf": "#ff7f0e",
    "rf-physical": "#2ca02c",
    "rf-fwd": "#d62728",
    FLOOR: "#4d4d4d",  # the ILC floor
    "shape": "#1b9e77",
    "random": "#d95f02",
    "burst": "#7570b3",
    "complex3d": "#e7298a",
    "vertical": "#66a61e",
    "horizontal": "#a6761d",
}

# Text sizes in points for figures seen small: a notebook shows them at 56 dpi (profiles.setup)
# and docs/results.md scales the 150-dpi PNGs to its page width. Constrained layout keeps
# labels, colour bars and figure legends from overlapping.
STYLE = {
    "font.size": 12,
    "axes.titlesize": 12,
    "axes.labelsize": 12,
    "xtick.labelsize": 11,
    "ytick.labelsize": 11,
    "legend.fontsize": 10,
    "legend.title_fontsize": 10,
    "lines.linewidth": 1.6,
    "figure.constrained_layout.use": True,
}


def _styled(draw):
    """Draw a figure under ``STYLE``. Ticks may be made again when the figure is shown, after
    the rc context has closed, so every axes also gets its tick label size explicitly."""

    @functools.wraps(draw)
    def styled(*args, **kwargs):
        # Only STYLE's own keys are set and put back: plt.rc_context restores every rcParam,
        # the backend too, and in a notebook the next figure then lands on a backend that does
        # not display it.
        saved = {key: plt.rcParams[key] for key in STYLE}
        plt.rcParams.update(STYLE)
        try:
            fig = draw(*args, **kwargs)
        finally:
            plt.rcParams.update(saved)
        for ax in fig.axes:
            ax.tick_params(labelsize=STYLE["xtick.labelsize"])
        return fig

    return styled


def colour(name, k: int = 0) -> str:
    """The colour of a model, the ILC floor, a reference family or a twin configuration; a name
    like "closed, vertical" takes its last part's; anything else the k-th of matplotlib's cycle."""
    name = str(name)
    return PALETTE.get(name) or PALETTE.get(name.rsplit(", ", 1)[-1]) or f"C{k % 10}"


def _plain_log(axis):
    """A log axis labelled in plain numbers (0.2, not 2 x 10^-1). Minor ticks get labels only
    where few decades are shown (every one under 0.6 decades, 2, 3 and 5 under 1.2, 2 and 5
    under 2.5, none beyond), so neighbouring labels never run into each other."""

    def minor(value, _):
        low, high = sorted(axis.get_view_interval())
        decades = np.log10(high / low) if low > 0 else np.inf
        mantissa = round(value / 10 ** np.floor(np.log10(value) + 1e-9))
        shown = decades < 0.6 or mantissa in ((2, 3, 5) if decades < 1.2 else (2, 5) if decades < 2.5 else ())
        return f"{value:g}" if shown else ""

    axis.set_major_formatter(FuncFormatter(lambda value, _: f"{value:g}"))
    axis.set_minor_formatter(FuncFormatter(minor))


def _figure_legend(fig, ax, columns: int):
    """One legend for a grid of panels, under it, from ``ax``'s lines: inside a panel it hides a path."""
    handles, labels = ax.get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside lower center", ncol=max(1, min(len(labels), columns)))


def save(fig, profile, name: str):
    """Write a figure under the profile's output folder (PNG) and return it for display."""
    fig.savefig(profile.output_dir / f"{name}.png")
    return fig


@_styled
def static_arcs(centerlines, closed_form_tips, labels):
    """Static rod shapes (x-y and x-z side views) with the closed-form arc tips marked."""
    fig, axes = plt.subplots(1, 2, figsize=(7.5, 2.8))
    for view, ax in zip((1, 2), axes):
        for line, tip, label in zip(centerlines, closed_form_tips, labels):
            (drawn,) = ax.plot(line[:, 0] * MM, line[:, view] * MM, label=label)
            ax.plot(tip[0] * MM, tip[view] * MM, "o", mfc="none", ms=9, color=drawn.get_color())
        ax.set(xlabel="x [mm]", ylabel=f"{'xyz'[view]} [mm]", aspect="equal")
    fig.suptitle("simulated shapes (lines) and closed-form arc tips (circles)")
    _figure_legend(fig, axes[0], 3)
    return fig


@_styled
def spectrum(frequencies, amplitude, theory_hz, model_hz, f_max=40.0):
    """Tip spectrum of a free vibration with Euler-Bernoulli and linearised-model lines."""
    fig, ax = plt.subplots(figsize=(5.8, 3.6))
    keep = frequencies <= f_max
    ax.semilogy(frequencies[keep], amplitude[keep], color="k", lw=1, label="simulated tip y")
    for k, f in enumerate(theory_hz):
        ax.axvline(f, color="C1", ls="--", label="Euler-Bernoulli" if k == 0 else None)
    for k, f in enumerate(model_hz):
        ax.axvline(f, color="C0", ls=":", label="GVS linearised" if k == 0 else None)
    ax.set(xlabel="frequency [Hz]", ylabel="normalised amplitude", ylim=(1e-5, 2))
    ax.legend()
    return fig


@_styled
def sag(simulated, elastica):
    """Horizontal rod sagging under its own weight: GVS vs the elastica BVP (x-z view)."""
    fig, ax = plt.subplots(figsize=(5.8, 3.6))
    ax.plot(elastica[:, 0] * MM, elastica[:, 2] * MM, "C1-", lw=4, alpha=0.5, label="elastica (solve_bvp)")
    ax.plot(simulated[:, 0] * MM, simulated[:, 2] * MM, "k.-", ms=3, lw=1, label="GVS")
    ax.set(xlabel="x [mm]", ylabel="z [mm]", aspect="equal")
    ax.legend()
    return fig


@_styled
def convergence(values: dict, errors: dict, xlabels: dict, tolerance=None):
    """Max tip error vs a discretisation parameter, one panel per parameter (log scale, mm)."""
    fig, axes = plt.subplots(1, len(errors), figsize=(3.4 * len(errors), 3.2), squeeze=False)
    for ax, name in zip(axes[0], errors):
        ax.semilogy(values[name], np.array(errors[name]) * MM, "o-", color="k")
        if tolerance is not None:
            ax.axhline(tolerance * MM, color="0.4", ls="--", lw=1)
        ax.set(xlabel=xlabels[name], ylabel="max tip error [mm]")
        _plain_log(ax.yaxis)
    return fig


@_styled
def episode(X, u, dt: float):
    """One episode: the tip path in 3D and the actuation over time."""
    fig = plt.figure(figsize=(8.5, 3.6))
    fig.get_layout_engine().set(wspace=0.1)  # the layout does not see the 3D panel's z label
    ax = fig.add_subplot(1, 2, 1, projection="3d")
    ax.plot(X[:, 1] * MM, X[:, 2] * MM, X[:, 0] * MM, lw=1)
    ax.set(xlabel="y [mm]", ylabel="z [mm]", zlabel="x [mm]")
    ax.set_box_aspect(None, zoom=0.85)  # room for the axis labels beside the next panel
    ax.invert_zaxis()
    ax2 = fig.add_subplot(1, 2, 2)
    t = np.arange(len(u)) * dt
    ax2.plot(t, u[:, 0], label="$u_1$")
    ax2.plot(t, u[:, 1], label="$u_2$")
    ax2.set(xlabel="t [s]", ylabel="u [N]")
    ax2.legend()
    return fig


@_styled
def excitations(u, dt: float, n_show: int = 6):
    """A few training actuation episodes, u_1 and u_2 over time."""
    fig, axes = plt.subplots(1, 2, figsize=(8.2, 3.0), sharey=True)
    t = np.arange(u.shape[1]) * dt
    for i, ax in enumerate(axes):
        ax.plot(t, u[:n_show, :, i].T, lw=1)
        ax.set(xlabel="t [s]", ylabel=f"$u_{i + 1}$ [N]")
    return fig


@_styled
def workspace(train_states, references, max_points: int = 20000, seed: int = 0):
    """Training tip positions (y-z density) with every reference path drawn over them in its
    family's colour, and the tip-speed distribution of the training data with each reference's
    peak speed marked."""
    fig, (ax, ax2) = plt.subplots(1, 2, figsize=(9.5, 4.2), gridspec_kw={"width_ratios": [1.1, 1]})
    points = train_states.reshape(-1, 6)
    sample = points[np.random.default_rng(seed).choice(len(points), min(max_points, len(points)), replace=False)]
    ax.plot(sample[:, 1] * MM, sample[:, 2] * MM, ".", ms=1, color="0.5", alpha=0.3)
    for r in references:
        ax.plot(r.states[r.mask, 1] * MM, r.states[r.mask, 2] * MM, lw=1.2, color=colour(r.family))
        peak = np.linalg.norm(r.states[r.mask, 3:], axis=1).max()
        ax2.axvline(peak, lw=1, alpha=0.8, color=colour(r.family))
    families = list(dict.fromkeys(r.family for r in references))
    ax.legend([Line2D([], [], color=colour(f)) for f in families], families, loc="upper right")
    ax.set(xlabel="y [mm]", ylabel="z [mm]", aspect="equal", title="training tips (grey) and references")
    ax2.hist(np.linalg.norm(points[:, 3:], axis=1), bins=80, density=True, color="0.6")
    ax2.set(xlabel="tip speed [m/s]", ylabel="density", yscale="log", title="speed; lines: reference peaks")
    return fig


@_styled
def coverage_bars(names, values, goal: float = 0.95):
    """Fraction of each reference's states inside the training distribution; bars below the
    goal (dashed) dark."""
    fig, ax = plt.subplots(figsize=(7, 3.2))
    ax.bar(names, values, color=["0.7" if v >= goal else "0.2" for v in values])
    ax.axhline(goal, color="k", ls="--", lw=1)
    ax.set(ylabel="coverage", ylim=(0, 1.05))
    ax.tick_params(axis="x", rotation=60)
    return fig


def _start_markers(ax, r):
    """A reference's Initial point (rest, diamond) and Start point (first scored state, dot)."""
    start = np.argmax(r.mask)
    ax.plot(r.states[0, 1] * MM, r.states[0, 2] * MM, "kD", mfc="none", label="Initial")
    ax.plot(r.states[start, 1] * MM, r.states[start, 2] * MM, "ko", label="Start")


@_styled
def tracking_grid(runs: dict, references: dict, names):
    """y-z tracking per reference (columns) for several models: the reference dashed, each
    model's open-loop tip path solid; the Initial point (diamond) and Start point (dot)."""
    fig, axes = plt.subplots(1, len(names), figsize=(3.0 * len(names), 3.3), squeeze=False)
    for ax, name in zip(axes[0], names):
        r = references[name]
        ax.plot(r.states[r.mask, 1] * MM, r.states[r.mask, 2] * MM, "k--", lw=1.5, label="reference")
        for k, (model, model_runs) in enumerate(runs.items()):
            X = model_runs[name]["states"]
            ax.plot(
                X[r.mask, 1] * MM, X[r.mask, 2] * MM, lw=1.2, color=colour(model, k), label=LABELS.get(model, model)
            )
        _start_markers(ax, r)
        ax.set(title=name, xlabel="y [mm]", ylabel="z [mm]", aspect="equal")
    _figure_legend(fig, axes[0, -1], 6)
    return fig


@_styled
def inputs_grid(runs: dict, references: dict, names, dt: float):
    """u_1 (top) and u_2 (bottom) over time per reference for several models; the true
    actuation dashed where the reference has one."""
    fig, axes = plt.subplots(2, len(names), figsize=(3.0 * len(names), 4.4), sharex="col", squeeze=False)
    for col, name in enumerate(names):
        r = references[name]
        for row in range(2):
            ax = axes[row, col]
            for k, (model, model_runs) in enumerate(runs.items()):
                u = model_runs[name]["u"]
                ax.plot(np.arange(len(u)) * dt, u[:, row], lw=1, color=colour(model, k), label=LABELS.get(model, model))
            if r.u_true is not None:
                ax.plot(np.arange(len(r.u_true)) * dt, r.u_true[:, row], "k--", lw=1, label="true")
            ax.set(ylabel=f"$u_{row + 1}$ [N]")
        axes[0, col].set_title(name)
        axes[1, col].set_xlabel("t [s]")
    _figure_legend(fig, axes[0, -1], 6)
    return fig


@_styled
def euler_sweep(steps, rmse_shape, rmse_random, latency_ms):
    """Tracking RMSE and per-step planning latency against the number of Euler steps."""
    fig, (ax, ax2) = plt.subplots(1, 2, figsize=(7.8, 3.3))
    ax.plot(steps, rmse_shape, "o-", color=colour("shape"), label="shapes")
    ax.plot(steps, rmse_random, "s-", color=colour("random"), label="random")
    ax.set(xscale="log", xlabel="Euler steps N", ylabel="RMSE [mm]")
    ax.legend()
    ax2.plot(steps, latency_ms, "o-", color="k")
    ax2.set(xscale="log", xlabel="Euler steps N", ylabel="latency per step [ms]")
    for a in (ax, ax2):
        a.set_xticks(steps, [f"{n:g}" for n in steps])
        a.xaxis.set_minor_locator(NullLocator())
    return fig


@_styled
def burst(reference, runs: dict, dt: float):
    """The burst circle: y-z paths (reference dashed) and tip speed over time per model."""
    fig, (ax, ax2) = plt.subplots(1, 2, figsize=(8.6, 3.6), gridspec_kw={"width_ratios": [1, 1.6]})
    m = reference.mask
    t = np.arange(len(m)) * dt
    ax.plot(reference.states[m, 1] * MM, reference.states[m, 2] * MM, "k--", lw=1.2, label="reference")
    ax2.plot(t[m], np.linalg.norm(reference.states[m, 3:], axis=1), "k--", lw=1.2, label="reference")
    for k, (model, run) in enumerate(runs.items()):
        X = run["states"]
        style = dict(lw=1, color=colour(model, k), label=LABELS.get(model, model))
        ax.plot(X[m, 1] * MM, X[m, 2] * MM, **style)
        ax2.plot(t[m], np.linalg.norm(X[m, 3:], axis=1), **style)
    ax.set(xlabel="y [mm]", ylabel="z [mm]", aspect="equal", title=reference.name)
    ax2.set(xlabel="t [s]", ylabel="tip speed [m/s]")
    ax2.legend(loc="upper left")
    return fig


@_styled
def break_curve(breakdown, limit_pct: float):
    """Per-revolution y-z RMSE (% of L) against the reference speed of the revolution, one
    line per model, with the break threshold. A model named "mode, configuration" (the twin's
    loops) takes its configuration's colour and a line style per mode."""
    fig, ax = plt.subplots(figsize=(6, 3.6))
    modes = list(dict.fromkeys(str(model).rsplit(", ", 1)[0] for model in breakdown["model"]))
    for k, (model, rows) in enumerate(breakdown.groupby("model", sort=False)):
        style = ("-", "--", "-.", ":")[modes.index(str(model).rsplit(", ", 1)[0]) % 4] if ", " in str(model) else "-"
        ax.plot(
            rows.reference_speed,
            rows.rmse_pct_L,
            marker="o",
            ms=3,
            ls=style,
            color=colour(model, k),
            label=LABELS.get(model, model),
        )
    ax.axhline(limit_pct, color="k", ls=":", lw=1, label=f"break: {limit_pct:g} % of L")
    ax.set(xlabel="reference tip speed of the revolution [m/s]", ylabel="y-z RMSE [% of L]", yscale="log")
    _plain_log(ax.yaxis)
    ax.legend()
    return fig


@_styled
def forward_inverse(reference, run, dt: float, model: str = "rf-fwd"):
    """Forward-then-inverse: the 3D tip path of the reference and of ``model``'s re-executed plan,
    and the true against the reconstructed u_1, u_2."""
    fig = plt.figure(figsize=(10.5, 3.6))
    fig.get_layout_engine().set(wspace=0.1)  # the layout does not see the 3D panel's z label
    ax = fig.add_subplot(1, 3, 1, projection="3d")
    ax.plot(*(reference.states[:, :3] * MM).T, "k--", lw=1.2, label="reference")
    ax.plot(*(run["states"][:, :3] * MM).T, lw=1, color=colour(model), label="re-executed")
    ax.set(xlabel="x [mm]", ylabel="y [mm]", zlabel="z [mm]", title=reference.name)
    ax.set_box_aspect(None, zoom=0.85)  # room for the axis labels beside the next panel
    ax.legend()
    t = np.arange(len(run["u"])) * dt
    for k in range(2):
        ax_u = fig.add_subplot(1, 3, k + 2)
        ax_u.plot(t, reference.u_true[:, k], "k--", lw=1.2, label="true")
        ax_u.plot(t, run["u"][:, k], lw=1, color=colour(model), label=f"reconstructed ({LABELS.get(model, model)})")
        ax_u.set(xlabel="t [s]", ylabel=f"$u_{k + 1}$ [N]")
    ax_u.legend()
    return fig


@_styled
def uncertainty(spread, error, families, burst_time, burst_spread, burst_error):
    """Left: mean actuation spread over noise draws against tracking RMSE, one dot per
    reference, coloured by family. Right: spread and tip error over the burst circle."""
    fig, (ax, ax2) = plt.subplots(1, 2, figsize=(9, 3.5))
    for k, family in enumerate(dict.fromkeys(families)):
        chosen = np.asarray(families) == family
        ax.scatter(np.asarray(spread)[chosen], np.asarray(error)[chosen], s=20, color=colour(family, k), label=family)
    ax.set(xscale="log", yscale="log", xlabel="actuation spread over noise draws [N]", ylabel="tracking RMSE [mm]")
    _plain_log(ax.xaxis)
    _plain_log(ax.yaxis)
    ax.legend()
    ax2.plot(burst_time, burst_spread, color="k")
    ax2.set(xlabel="t [s]", ylabel="actuation spread [N] (black)")
    twin = ax2.twinx()
    twin.plot(burst_time, np.asarray(burst_error) * MM, color=colour("burst"), lw=1)
    twin.set_ylabel("tip error [mm]", color=colour("burst"))
    twin.grid(False)
    return fig


@_styled
def twin_tracking(runs: dict, references: dict, names, dt: float):
    """Camera-measured y-z tracking on the hardware twin: rows are configurations, columns
    shapes; the reference dashed, the camera track solid (the configuration's colour), Initial
    (diamond) and Start (dot)."""
    fig, axes = plt.subplots(len(runs), len(names), figsize=(3.2 * len(names), 3.2 * len(runs)), squeeze=False)
    for row, (config, config_runs) in enumerate(runs.items()):
        for ax, name in zip(axes[row], names):
            r, run = references[config][name], config_runs[name]
            scored = r.mask[np.round(run["frame_times"] / dt).astype(int)]
            ax.plot(r.states[r.mask, 1] * MM, r.states[r.mask, 2] * MM, "k--", lw=1.2, label="reference")
            ax.plot(
                run["tracked"][scored, 1] * MM,
                run["tracked"][scored, 2] * MM,
                lw=1.2,
                color=colour(config, row),
                label="camera",
            )
            _start_markers(ax, r)
            ax.set(title=f"{name} ({config})", xlabel="y [mm]", ylabel="z [mm]", aspect="equal")
    _figure_legend(fig, axes[0, -1], 2 * len(names))
    return fig


@_styled
def images(pictures: dict, columns: int = 2):
    """BGR images (OpenCV order) in a grid, titled by their keys."""
    rows = -(-len(pictures) // columns)
    fig, axes = plt.subplots(rows, columns, figsize=(3.7 * columns, 2.9 * rows), squeeze=False)
    for ax in axes.flat:
        ax.axis("off")
    for ax, (title, picture) in zip(axes.flat, pictures.items()):
        ax.imshow(picture[..., ::-1])
        ax.set_title(title)
    return fig


@_styled
def intervals(summaries: dict, labels: dict, xlabel: str = "RMSE [mm]"):
    """One panel per title in ``summaries`` ({title: DataFrame indexed by model with mean, low,
    high}): each model's mean and interval in its colour, on a log axis (the floor sits far below)."""
    fig, axes = plt.subplots(1, len(summaries), figsize=(3.8 * len(summaries) + 1.0, 3.2), sharey=True)
    for ax, (title, table) in zip(np.atleast_1d(axes), summaries.items()):
        y = np.arange(len(table))[::-1]
        for k, (model, at) in enumerate(zip(table.index, y)):
            row = table.loc[model]
            ax.errorbar(
                row["mean"],
                at,
                xerr=[[row["mean"] - row["low"]], [row["high"] - row["mean"]]],
                fmt="o",
                color=colour(model, k),
                capsize=3,
            )
        ax.set(xscale="log", xlabel=xlabel, title=title, yticks=y, yticklabels=[labels.get(m, m) for m in table.index])
        _plain_log(ax.xaxis)
    return fig


def _two_digits(value: float) -> str:
    """A table cell: two significant digits, never in exponent form (110, not 1.1e+02)."""
    return f"{value:.0f}" if abs(value) >= 10 else f"{value:.2g}"


@_styled
def condition_grid(table, labels: dict, title: str):
    """A condition x model table of RMSE (mm) as a heatmap on a log colour scale, values written in."""
    values = table.to_numpy(float)
    fig, ax = plt.subplots(figsize=(0.95 * values.shape[1] + 2.3, 0.34 * values.shape[0] + 1.4))
    norm = LogNorm(np.nanmin(values), np.nanmax(values))
    image = ax.imshow(values, norm=norm, cmap="viridis", aspect="auto")
    for (i, j), v in np.ndenumerate(values):
        if np.isfinite(v):
            ax.text(j, i, _two_digits(v), ha="center", va="center", fontsize=10, color="w" if norm(v) < 0.6 else "k")
    ax.set(
        xticks=range(values.shape[1]),
        xticklabels=[labels.get(m, m) for m in table.columns],
        yticks=range(values.shape[0]),
        yticklabels=table.index,
        title=title,
    )
    ax.tick_params(axis="x", rotation=30)
    plt.setp(ax.get_xticklabels(), ha="right", rotation_mode="anchor")
    ax.grid(False)
    bar = fig.colorbar(image, ax=ax, label="RMSE [mm]")
    _plain_log(bar.ax.yaxis)
    return fig


def band_lines(ax, summary, x: str, by: str, label=str):
    """One line of ``mean`` against column ``x`` per group of ``by`` in the group's colour, with
    its interval (``low``..``high``) as a band: the studies' curves with their 95 % intervals."""
    for k, (group, part) in enumerate(summary.groupby(by, sort=False)):
        (line,) = ax.plot(part[x], part["mean"], "o-", ms=4, color=colour(group, k), label=label(group))
        ax.fill_between(part[x], part["low"], part["high"], color=line.get_color(), alpha=0.15)


@_styled
def against_speed(summary, coverage, labels: dict):
    """RMSE against the shapes' mean tip speed per model, with interval bands, and the
    references' coverage by the training states on a second axis."""
    fig, ax = plt.subplots(figsize=(6.4, 3.4))
    band_lines(ax, summary, "speed", "model", lambda model: labels.get(model, model))
    ax.set(xlabel="mean tip speed of the shapes [m/s]", ylabel="RMSE [mm]", yscale="log")
    _plain_log(ax.yaxis)
    twin = ax.twinx()
    twin.plot(coverage.index, coverage.values, "k--", lw=1)
    twin.set(ylabel="coverage (dashed)", ylim=(0, 1.05))
    twin.grid(False)
    _figure_legend(fig, ax, 4)
    return fig


@_styled
def latency_curve(closed, open_loop):
    """Closed-loop RMSE (mean over the shapes, mm) against camera latency, one line per
    configuration (``closed``: indexed by latency in s, columns configurations), with the
    open loop (dashed, ``open_loop``: configuration -> mm) for comparison."""
    fig, ax = plt.subplots(figsize=(4.6, 3.0))
    for k, config in enumerate(closed.columns):
        (line,) = ax.plot(closed.index * MM, closed[config], "o-", color=colour(config, k), label=f"closed, {config}")
        ax.axhline(open_loop[config], color=line.get_color(), ls="--", lw=1, label=f"open, {config}")
    ax.set(xlabel="camera latency [ms]", ylabel="mean RMSE, shapes [mm]", ylim=(0, None))
    _figure_legend(fig, ax, 2)
    return fig


@_styled
def identified_terms(identified):
    """Identified reality-gap terms against the truth (``identified``: rows E, eta, rho
    (relative) and motor_lag (s); columns the truth and each configuration's fit)."""
    relative, lag = identified.drop(index="motor_lag"), identified.loc["motor_lag"]
    fig, (ax, ax_lag) = plt.subplots(1, 2, figsize=(7.4, 3.1), gridspec_kw=dict(width_ratios=(3, 1)))
    width = 0.8 / len(identified.columns)
    for k, column in enumerate(identified.columns):
        style = dict(color="k" if column == "truth" else colour(column, k), label=column, width=width)
        ax.bar(np.arange(len(relative)) + k * width, 100 * relative[column], **style)
        ax_lag.bar(k * width, MM * lag[column], **style)
    ax.set(
        xticks=np.arange(len(relative)) + width * (len(identified.columns) - 1) / 2,
        xticklabels=relative.index,
        ylabel="error against the model rod [%]",
    )
    ax.axhline(0, color="k", lw=0.8)
    ax_lag.set(xticks=[], xlabel="motor lag", ylabel="[ms]")
    ax.legend()
    return fig


@_styled
def against_data_size(summary, labels: dict):
    """Tracking RMSE against the training episodes per model, with interval bands, one panel
    per reference family (``summary``: model, episodes, family, mean, low, high)."""
    families = list(dict.fromkeys(summary["family"]))
    fig, axes = plt.subplots(1, len(families), figsize=(4.4 * len(families), 3.5), squeeze=False)
    sizes = sorted(set(summary["episodes"]))
    for ax, family in zip(axes[0], families):
        band_lines(
            ax, summary[summary["family"] == family], "episodes", "model", lambda model: labels.get(model, model)
        )
        ax.set(xscale="log", yscale="log", xlabel="training episodes", ylabel="RMSE [mm]", title=f"{family} references")
        _plain_log(ax.yaxis)
        ax.set_xticks(sizes, [f"{size:g}" for size in sizes])
        ax.xaxis.set_minor_locator(NullLocator())
    _figure_legend(fig, axes[0, 0], 4)
    return fig


@_styled
def ambiguity_panel(per_step, labels: dict):
    """Per dataset variant: each model's per-step u error (bars) beside the data's conditional
    spread and its floor (per input, markers); and the flows' draw spread against their error
    (Spearman correlation per transition). ``per_step``: indexed by (variant, model)."""
    variants = list(dict.fromkeys(per_step.index.get_level_values("variant")))
    models = list(dict.fromkeys(per_step.index.get_level_values("model")))
    fig, (ax, ax_rank) = plt.subplots(1, 2, figsize=(10, 3.7), gridspec_kw=dict(width_ratios=(2, 1)))
    width, x = 0.8 / len(models), np.arange(len(variants))
    for k, model in enumerate(models):
        part = per_step.xs(model, level="model").reindex(variants)
        style = dict(color=colour(model, k), label=labels.get(model, model))
        ax.bar(x + k * width, part["u_rmse_test"], width, **style)
        if "spread_error_spearman" in part and part["spread_error_spearman"].notna().any():
            ax_rank.bar(x + k * width, part["spread_error_spearman"], width, **style)
    first = per_step.groupby(level="variant", sort=False).first().reindex(variants)
    centre = x + width * (len(models) - 1) / 2
    ax.plot(centre, first["conditional_spread"] / np.sqrt(2), "k_", ms=18, mew=2.5, label="conditional spread")
    ax.plot(
        centre, first["conditional_spread_floor"] / np.sqrt(2), "k_", ms=18, mew=1.5, alpha=0.4, label="estimator floor"
    )
    for a in (ax, ax_rank):
        a.set_xticks(centre, variants, rotation=30, ha="right", rotation_mode="anchor")
    ax.set(ylabel="per-step u error,\nRMS per input [N]", yscale="log")
    _plain_log(ax.yaxis)
    ax_rank.set(ylabel="Spearman(draw spread, error)", ylim=(-0.2, 1))
    ax_rank.axhline(0, color="k", lw=0.8)
    handles, names = ax.get_legend_handles_labels()
    fig.legend(handles, names, loc="outside upper center", ncol=len(names))
    return fig


@_styled
def regime_map(table, labels: dict):
    """Flow minus MLP (z = 0 plans) per dataset variant, the variants in order of their measured
    ambiguity (conditional spread over its estimator floor, in brackets; 1: none measurable):
    tracking RMSE (mm; filled: shapes, open: random references) and the per-step u error (N),
    with 95 % intervals, each flow in its colour; below zero the flow wins. Each variant is
    named once, on the x axis, so no two labels can overlap."""
    ambiguity = table["conditional_spread"] / table["spread_floor"]
    ambiguity = ambiguity.groupby(table["variant"], sort=False).first().sort_values(kind="stable")
    slot = {variant: k for k, variant in enumerate(ambiguity.index)}
    flows = list(dict.fromkeys(table["a"]))
    families = {"shape": "o", "random": "s"}
    fig, (ax, ax_step) = plt.subplots(1, 2, figsize=(10, 4.1))

    def dodge(k, n):  # side by side within a variant's slot
        return 0.0 if n == 1 else 0.5 * (k / (n - 1) - 0.5)

    for row in table.itertuples():
        k, c = flows.index(row.a), colour(row.a)
        error = [[row.estimate - row.low], [row.high - row.estimate]] if np.isfinite(row.low) else None
        if row.family == "step":
            ax_step.errorbar(slot[row.variant] + dodge(k, len(flows)), row.estimate, error, fmt="D", color=c, capsize=3)
            continue
        j, marker = list(families).index(row.family), families[row.family]
        ax.errorbar(
            slot[row.variant] + dodge(k * len(families) + j, len(flows) * len(families)),
            row.estimate,
            error,
            fmt=marker,
            color=c,
            mfc=c if row.family == "shape" else "white",
            capsize=3,
        )
    names = [f"{variant} ({level:.1f})" for variant, level in ambiguity.items()]
    for a, title, unit in ((ax, "tracking RMSE", "mm"), (ax_step, "per-step u error", "N")):
        a.axhline(0, color="k", lw=0.8)
        a.set_xticks(range(len(names)), names, rotation=30, ha="right", rotation_mode="anchor")
        a.set(xlim=(-0.6, len(names) - 0.4), title=f"{title} (below 0: the flow wins)", ylabel=f"flow - MLP [{unit}]")
    ax.set_yscale("symlog", linthresh=1.0)  # tenths of a mm and tens of mm on one axis; linear within 1 mm
    ax.yaxis.set_major_formatter(FuncFormatter(lambda value, _: f"{value:g}"))
    handles = [
        Line2D([], [], color=colour(flow), marker="o", ls="", label=f"{labels.get(flow, flow)} - MLP") for flow in flows
    ]
    handles += [
        Line2D([], [], color="0.3", marker=m, mfc="0.3" if f == "shape" else "white", ls="", label=f"{f} references")
        for f, m in families.items()
    ]
    fig.legend(handles=handles, loc="outside upper center", ncol=len(handles))
    fig.supxlabel("dataset variant (conditional spread / estimator floor), in order of ambiguity")
    return fig


@_styled
def consistency_weight(summary, diagnostics, taus):
    """RF-FWD's consistency weight: tracking RMSE against lambda per family with interval bands
    (``summary``: consistency, family, mean, low, high); and, per lambda, the u error of the
    loss's one-step endpoint estimate (solid) and of a short Euler rollout (dashed) against tau
    (``diagnostics``: indexed by lambda, columns one_step_u_error_tau<t>, euler_u_error_tau<t>)."""
    fig, (ax, ax_tau) = plt.subplots(1, 2, figsize=(9.4, 3.6))
    band_lines(ax, summary, "consistency", "family", lambda family: f"{family} references")
    weights = sorted(set(summary["consistency"]))
    ax.set_xscale("symlog", linthresh=0.03)  # lambda = 0 (RF) on the same axis as 0.03-1
    ax.set_xticks(weights, [f"{w:g}" for w in weights])
    ax.xaxis.set_minor_locator(NullLocator())
    ax.set(xlabel="consistency weight lambda", ylabel="RMSE [mm]", yscale="log", xlim=(0, 1.2 * max(weights)))
    _plain_log(ax.yaxis)
    ax.legend()
    shades = plt.get_cmap("viridis")(np.linspace(0, 0.85, len(diagnostics)))  # an ordered weight: an ordered colour
    for shade, (weight, row) in zip(shades, diagnostics.iterrows()):
        for label, style in (("one_step", "-"), ("euler", "--")):
            ax_tau.plot(
                taus,
                [row[f"{label}_u_error_tau{t:g}"] for t in taus],
                style,
                color=shade,
                label=f"lambda = {weight:g}" if label == "one_step" else None,
            )
    ax_tau.plot([], [], "k-", label="one step")
    ax_tau.plot([], [], "k--", label="Euler rollout")
    ax_tau.set(xlabel="tau", ylabel="endpoint u error [N]")
    ax_tau.legend(ncol=2)
    return fig


@_styled
def redundancy(along, histories: dict, shapes: dict, disks: dict, instant: int):
    """One tip path reached statically by several input histories of a redundant rod, each
    history in its own line style: its inputs along the path (``histories``: {label: u (K, m)},
    a colour per input), the rod's centreline under it at sample ``instant`` seen along the rod's
    axis (``shapes``: {label: (N+1, 3)}), and the paths of the tip (thick) and of the inner disks
    (thin) in y-z (``disks``: {label: (K, S, 3)}, the tip last), the instant's disks circled.
    ``along``: the path's parameter (K,), its angle in degrees."""
    styles = dict(zip(histories, ["-", "--", ":", "-."]))
    fig, (ax_u, ax_rod, ax_path) = plt.subplots(1, 3, figsize=(10.5, 3.6))
    for label, u in histories.items():
        for i in range(u.shape[1]):
            ax_u.plot(along, u[:, i], styles[label], color=f"C{i}")
    ax_u.axvline(along[instant], color="0.6", lw=0.8)
    ax_u.set(xlabel="along the path [deg]", ylabel="u [N]", title="input histories")
    for label, line in shapes.items():
        ax_rod.plot(line[:, 1] * MM, line[:, 2] * MM, styles[label], color="k")
        ax_rod.plot(disks[label][instant, :, 1] * MM, disks[label][instant, :, 2] * MM, "o", mfc="none", color="k")
    ax_rod.plot(0, 0, "ks", ms=4)
    ax_rod.set(xlabel="y [mm]", ylabel="z [mm]", title="the rod, seen along x (base: square)", aspect="equal")
    for label, points in disks.items():
        for s in range(points.shape[1]):
            tip = s == points.shape[1] - 1
            ax_path.plot(
                points[:, s, 1] * MM,
                points[:, s, 2] * MM,
                styles[label],
                color="k" if tip else "0.5",
                lw=2.4 if tip else 1.2,
            )
        ax_path.plot(points[instant, :, 1] * MM, points[instant, :, 2] * MM, "o", mfc="none", color="k")
    ax_path.set(xlabel="y [mm]", ylabel="z [mm]", title="tip (black), middle disk (grey)", aspect="equal")
    handles = [
        Line2D([], [], color=f"C{i}", label=f"$u_{i + 1}$") for i in range(next(iter(histories.values())).shape[1])
    ]
    handles += [Line2D([], [], color="k", ls=style, label=label) for label, style in styles.items()]
    fig.legend(handles=handles, loc="outside lower center", ncol=len(handles))
    return fig


@_styled
def tracking_depth(runs: dict, references: dict, names, dt: float):
    """Open-loop tracking of 3-D references per reference (columns): the y-z path (top) and the
    depth x over time (bottom), the reference dashed, each run solid in its model's colour.
    ``runs``: {"observation, model": {reference name: dict(states=(T+1, d))}}; a second
    observation of the same model is drawn dotted."""
    fig, axes = plt.subplots(2, len(names), figsize=(3.3 * len(names), 5.2), squeeze=False)
    observations = list(dict.fromkeys(label.split(", ")[0] for label in runs))
    for col, name in enumerate(names):
        r, (ax_yz, ax_x) = references[name], axes[:, col]
        t = np.arange(len(r.states)) * dt
        ax_yz.plot(r.states[r.mask, 1] * MM, r.states[r.mask, 2] * MM, "k--", lw=1.5, label="reference")
        ax_x.plot(t[r.mask], r.states[r.mask, 0] * MM, "k--", lw=1.5)
        for k, (label, model_runs) in enumerate(runs.items()):
            observation, model = label.split(", ")
            X = model_runs[name]["states"]
            style = dict(
                color=colour(model, k),
                ls="-" if observation == observations[0] else ":",
                lw=1.2,
                label=f"{LABELS.get(model, model)} ({observation})",
            )
            ax_yz.plot(X[r.mask, 1] * MM, X[r.mask, 2] * MM, **style)
            ax_x.plot(t[r.mask], X[r.mask, 0] * MM, **style)
        _start_markers(ax_yz, r)
        ax_yz.set(title=name, xlabel="y [mm]", ylabel="z [mm]", aspect="equal")
        ax_x.set(xlabel="t [s]", ylabel="depth x [mm]")
    _figure_legend(fig, axes[0, -1], 4)
    return fig


@_styled
def recording(frames_time, frames_tip, smoothed, column: int = 1):
    """One recorded run's tip coordinate ``column`` (1: lateral y): the camera's frames
    (``frames_time`` (F,) s, ``frames_tip`` (F, k) m, NaN where a frame was lost) as dots and the
    smoother's estimate (``smoothed``: a ``recordings.Recording``) as a line (left), and its
    velocity beside finite differences of the frames (right), which the smoother replaces."""
    k = smoothed.states.shape[1] // 2
    kept = np.isfinite(frames_tip[:, column])
    t, x = frames_time[kept], frames_tip[kept, column]
    fig, (ax_p, ax_v) = plt.subplots(1, 2, figsize=(9.0, 3.0))
    ax_p.plot(t, x * MM, ".", color="0.55", ms=4, label="camera frames")
    ax_p.plot(smoothed.times, smoothed.states[:, column] * MM, color="k", lw=1.4, label="smoothed")
    ax_p.set(xlabel="t [s]", ylabel=f"{smoothed.tip_columns[column].split('_')[0]} [mm]", title="tip position")
    ax_v.plot((t[1:] + t[:-1]) / 2, np.diff(x) / np.diff(t) * MM, color="0.55", lw=0.8, label="finite differences")
    ax_v.plot(smoothed.times, smoothed.states[:, k + column] * MM, color="k", lw=1.4, label="smoother (RTS)")
    ax_v.set(xlabel="t [s]", ylabel="velocity [mm/s]", title="tip velocity")
    ax_v.legend(loc="best")
    ax_p.legend(loc="best")
    return fig


@_styled
def hysteresis(loops: dict):
    """Hysteresis loops of the twin (``loops``: {friction coefficient: hysteresis.HysteresisLoop}): the
    lateral tip against u1 along the slower cycle's down (solid) and up (dashed) branches (left),
    and the gap between the branches once rate effects are removed, in % of the reach (right)."""
    fig, (ax_loop, ax_gap) = plt.subplots(1, 2, figsize=(9.0, 3.2))
    for k, (mu, loop) in enumerate(loops.items()):
        style = dict(color=f"C{k}")
        ax_loop.plot(loop.down[:, 0], loop.down[:, 1] * MM, "-", **style, label=f"$\\mu$ = {mu:g}")
        ax_loop.plot(loop.up[:, 0], loop.up[:, 1] * MM, "--", **style)
        ax_gap.plot(loop.u, 100 * loop.gap, **style, label=f"$\\mu$ = {mu:g}: width {100 * loop.width:.2f} %")
    ax_loop.set(xlabel="$u_1$ [N]", ylabel="lateral tip y [mm]", title="down (solid) and up (dashed)")
    ax_gap.axhline(0, color="0.6", lw=0.8)
    ax_gap.set(xlabel="$u_1$ [N]", ylabel="down - up [% of reach]", title="the loop, rate effects removed")
    ax_loop.legend(loc="upper left")
    ax_gap.legend(loc="lower center")
    return fig


@_styled
def resolution_curves(curve):
    """A referee's resolution curves: one panel per family, each perturbation of the recorded
    inputs against the judged change of the tip error (mm) it causes, with its bootstrap interval,
    one colour per judge (``trunk_v2.resolution``'s rows). Above zero: the judge sees the input
    is worse; an interval below zero: it rates a worse input better."""
    families = list(dict.fromkeys(curve.family))
    fig, axes = plt.subplots(1, len(families), figsize=(3.6 * len(families) + 0.8, 3.4), sharey=True)
    for ax, family in zip(np.atleast_1d(axes), families):
        part = curve[curve.family == family]
        inputs = list(dict.fromkeys(part.input))
        for k, (judge, rows) in enumerate(part.groupby("judge", sort=False)):
            x = np.array([inputs.index(name) for name in rows.input]) + 0.15 * (k - 0.5)
            error = [rows.difference - rows.low, rows.high - rows.difference]
            ax.errorbar(x, rows.difference, yerr=error, fmt="o", color=f"C{k}", capsize=2, label=judge)
        ax.axhline(0, color="0.5", lw=0.8)
        ax.set(title=family, xticks=range(len(inputs)))
        ax.set_yscale("symlog", linthresh=1)  # linear within +-1 mm, where the resolutions lie
        ax.yaxis.set_major_formatter(FuncFormatter(lambda value, _: f"{value:g}"))
        ax.set_xticklabels(inputs, rotation=60, ha="right")
    np.atleast_1d(axes)[0].set_ylabel("judged change [mm]")
    np.atleast_1d(axes)[-1].legend()
    return fig
