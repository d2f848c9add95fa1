"""Every figure of the notebooks: one function per figure type, data in, Figure out.

Lengths arrive in SI units and are drawn in mm.
"""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.ticker import FuncFormatter

MM = 1e3  # m -> mm for axes


def save(fig, profile, name: str):
    """Write a figure under the profile's output folder (PNG) and return it for display."""
    fig.savefig(profile.output_dir / f"{name}.png")
    return fig


def static_arcs(centerlines, closed_form_tips, labels):
    """Static rod shapes (x-y and x-z side views) with the closed-form arc tips marked."""
    fig, axes = plt.subplots(1, 2, figsize=(9, 3.8))
    for view, ax in zip((1, 2), axes):
        for line, tip, label in zip(centerlines, closed_form_tips, labels):
            (drawn,) = ax.plot(line[:, 0] * MM, line[:, view] * MM, label=label)
            ax.plot(tip[0] * MM, tip[view] * MM, "o", mfc="none", ms=9, color=drawn.get_color())
        ax.set(xlabel="x [mm]", ylabel=f"{'xyz'[view]} [mm]", aspect="equal")
    axes[0].set_title("simulated shape; circle: closed-form arc tip")
    axes[1].legend(fontsize=7, loc="lower left")
    return fig


def spectrum(frequencies, amplitude, theory_hz, model_hz, f_max=40.0):
    """Tip spectrum of a free vibration with Euler-Bernoulli and linearised-model lines."""
    fig, ax = plt.subplots()
    keep = frequencies <= f_max
    ax.semilogy(frequencies[keep], amplitude[keep], color="k", lw=1, label="simulated tip y")
    for k, f in enumerate(theory_hz):
        ax.axvline(f, color="C1", ls="--", label="Euler-Bernoulli" if k == 0 else None)
    for k, f in enumerate(model_hz):
        ax.axvline(f, color="C0", ls=":", label="GVS linearised" if k == 0 else None)
    ax.set(xlabel="frequency [Hz]", ylabel="normalised amplitude", ylim=(1e-5, 2))
    ax.legend()
    return fig


def sag(simulated, elastica):
    """Horizontal rod sagging under its own weight: GVS vs the elastica BVP (x-z view)."""
    fig, ax = plt.subplots()
    ax.plot(elastica[:, 0] * MM, elastica[:, 2] * MM, "C1-", lw=4, alpha=0.5, label="elastica (solve_bvp)")
    ax.plot(simulated[:, 0] * MM, simulated[:, 2] * MM, "k.-", ms=3, lw=1, label="GVS")
    ax.set(xlabel="x [mm]", ylabel="z [mm]", aspect="equal")
    ax.legend()
    return fig


def convergence(values: dict, errors: dict, xlabels: dict, tolerance=None):
    """Max tip error vs a discretisation parameter, one panel per parameter (log scale, mm)."""
    fig, axes = plt.subplots(1, len(errors), figsize=(4 * len(errors), 3.5), squeeze=False)
    for ax, name in zip(axes[0], errors):
        ax.semilogy(values[name], np.array(errors[name]) * MM, "o-")
        if tolerance is not None:
            ax.axhline(tolerance * MM, color="C3", ls="--", lw=1)
        ax.set(xlabel=xlabels[name], ylabel="max tip error [mm]")
    return fig


def episode(X, u, dt: float):
    """One episode: the tip path in 3D and the actuation over time."""
    fig = plt.figure(figsize=(10, 4))
    ax = fig.add_subplot(1, 2, 1, projection="3d")
    ax.plot(X[:, 1] * MM, X[:, 2] * MM, X[:, 0] * MM, lw=1)
    ax.set(xlabel="y [mm]", ylabel="z [mm]", zlabel="x [mm]")
    ax.invert_zaxis()
    ax2 = fig.add_subplot(1, 2, 2)
    t = np.arange(len(u)) * dt
    ax2.plot(t, u[:, 0], label="$u_1$")
    ax2.plot(t, u[:, 1], label="$u_2$")
    ax2.set(xlabel="t [s]", ylabel="u [N]")
    ax2.legend()
    return fig


def excitations(u, dt: float, n_show: int = 6):
    """A few training actuation episodes, u_1 and u_2 over time."""
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.2), sharey=True)
    t = np.arange(u.shape[1]) * dt
    for i, ax in enumerate(axes):
        ax.plot(t, u[:n_show, :, i].T, lw=1)
        ax.set(xlabel="t [s]", ylabel=f"$u_{i + 1}$ [N]")
    return fig


def workspace(train_states, references, max_points: int = 20000, seed: int = 0):
    """Training tip positions (y-z density) with every reference path drawn over them,
    and the tip-speed distribution of the training data with the references' speeds marked."""
    fig, (ax, ax2) = plt.subplots(1, 2, figsize=(11, 4.5), gridspec_kw={"width_ratios": [1.1, 1]})
    points = train_states.reshape(-1, 6)
    sample = points[np.random.default_rng(seed).choice(len(points), min(max_points, len(points)), replace=False)]
    ax.plot(sample[:, 1] * MM, sample[:, 2] * MM, ".", ms=1, color="0.5", alpha=0.3)
    for r in references:
        ax.plot(r.states[r.mask, 1] * MM, r.states[r.mask, 2] * MM, lw=1.2, label=r.name)
    ax.set(xlabel="y [mm]", ylabel="z [mm]", aspect="equal", title="training tips (grey) and references")
    ax.legend(fontsize=6, ncol=2, loc="upper right")
    speed = np.linalg.norm(points[:, 3:], axis=1)
    ax2.hist(speed, bins=80, density=True, color="0.6", label="training")
    for r in references:
        ax2.axvline(np.linalg.norm(r.states[r.mask, 3:], axis=1).max(), lw=0.8, alpha=0.7)
    ax2.set(xlabel="tip speed [m/s]", ylabel="density", yscale="log", title="speed; lines: reference peaks")
    return fig


def coverage_bars(names, values, goal: float = 0.95):
    """Fraction of each reference's states inside the training distribution."""
    fig, ax = plt.subplots(figsize=(8, 3.2))
    ax.bar(names, values, color=["C0" if v >= goal else "C3" for v in values])
    ax.axhline(goal, color="k", ls="--", lw=1)
    ax.set(ylabel="coverage", ylim=(0, 1.05))
    ax.tick_params(axis="x", rotation=60, labelsize=8)
    return fig


def tracking_grid(runs: dict, references: dict, names):
    """y-z tracking per reference (columns) for several models: the reference dashed, each
    model's open-loop tip path solid; the Initial point (diamond) and Start point (dot)."""
    fig, axes = plt.subplots(1, len(names), figsize=(3.6 * len(names), 3.6), squeeze=False)
    for ax, name in zip(axes[0], names):
        r = references[name]
        ax.plot(r.states[r.mask, 1] * MM, r.states[r.mask, 2] * MM, "k--", lw=1.5, label="reference")
        for model, model_runs in runs.items():
            X = model_runs[name]["states"]
            ax.plot(X[r.mask, 1] * MM, X[r.mask, 2] * MM, lw=1, label=model)
        start = np.argmax(r.mask)
        ax.plot(r.states[0, 1] * MM, r.states[0, 2] * MM, "kD", mfc="none", label="Initial")
        ax.plot(r.states[start, 1] * MM, r.states[start, 2] * MM, "ko", label="Start")
        ax.set(title=name, xlabel="y [mm]", ylabel="z [mm]", aspect="equal")
    axes[0, -1].legend(fontsize=7)
    return fig


def inputs_grid(runs: dict, references: dict, names, dt: float):
    """u_1 (top) and u_2 (bottom) over time per reference for several models; the true
    actuation dashed where the reference has one."""
    fig, axes = plt.subplots(2, len(names), figsize=(3.6 * len(names), 4.6), sharex="col", squeeze=False)
    for col, name in enumerate(names):
        r = references[name]
        for row in range(2):
            ax = axes[row, col]
            for model, model_runs in runs.items():
                u = model_runs[name]["u"]
                ax.plot(np.arange(len(u)) * dt, u[:, row], lw=0.9, label=model)
            if r.u_true is not None:
                ax.plot(np.arange(len(r.u_true)) * dt, r.u_true[:, row], "k--", lw=1, label="true")
            ax.set(ylabel=f"$u_{row + 1}$ [N]")
        axes[0, col].set_title(name)
        axes[1, col].set_xlabel("t [s]")
    axes[0, -1].legend(fontsize=7)
    return fig


def euler_sweep(steps, rmse_shape, rmse_random, latency_ms):
    """Tracking RMSE and per-step planning latency against the number of Euler steps."""
    fig, (ax, ax2) = plt.subplots(1, 2, figsize=(9, 3.4))
    ax.plot(steps, rmse_shape, "o-", label="shapes")
    ax.plot(steps, rmse_random, "s-", label="random")
    ax.set(xscale="log", xlabel="Euler steps N", ylabel="RMSE [mm]")
    ax.legend()
    ax2.plot(steps, latency_ms, "o-", color="C2")
    ax2.set(xscale="log", xlabel="Euler steps N", ylabel="latency per control step [ms]")
    return fig


def burst(reference, runs: dict, dt: float):
    """The burst circle: y-z paths (reference dashed) and tip speed over time per model."""
    fig, (ax, ax2) = plt.subplots(1, 2, figsize=(10, 4), gridspec_kw={"width_ratios": [1, 1.6]})
    m = reference.mask
    t = np.arange(len(m)) * dt
    ax.plot(reference.states[m, 1] * MM, reference.states[m, 2] * MM, "k--", lw=1.2, label="reference")
    ax2.plot(t[m], np.linalg.norm(reference.states[m, 3:], axis=1), "k--", lw=1.2, label="reference")
    for model, run in runs.items():
        X = run["states"]
        ax.plot(X[m, 1] * MM, X[m, 2] * MM, lw=0.8, label=model)
        ax2.plot(t[m], np.linalg.norm(X[m, 3:], axis=1), lw=0.8, label=model)
    ax.set(xlabel="y [mm]", ylabel="z [mm]", aspect="equal", title=reference.name)
    ax2.set(xlabel="t [s]", ylabel="tip speed [m/s]")
    ax2.legend(fontsize=8)
    return fig


def break_curve(breakdown, limit_pct: float):
    """Per-revolution y-z RMSE (% of L) against the reference speed of the revolution, one
    line per model, with the break threshold."""
    fig, ax = plt.subplots(figsize=(6.4, 3.8))
    for model, rows in breakdown.groupby("model", sort=False):
        ax.plot(rows.reference_speed, rows.rmse_pct_L, "o-", ms=3, label=model)
    ax.axhline(limit_pct, color="k", ls=":", label=f"break: {limit_pct:g} % of L")
    ax.set(xlabel="reference tip speed of the revolution [m/s]", ylabel="y-z RMSE [% of L]", yscale="log")
    ax.legend(fontsize=8)
    return fig


def forward_inverse(reference, run, dt: float):
    """Forward-then-inverse: the 3D tip path of the reference and of the re-executed plan, and
    the true against the reconstructed u_1, u_2."""
    fig = plt.figure(figsize=(11, 3.8))
    ax = fig.add_subplot(1, 3, 1, projection="3d")
    ax.plot(*(reference.states[:, :3] * MM).T, "k--", lw=1.2, label="reference")
    ax.plot(*(run["states"][:, :3] * MM).T, lw=0.9, label="re-executed")
    ax.set(xlabel="x [mm]", ylabel="y [mm]", zlabel="z [mm]", title=reference.name)
    ax.legend(fontsize=7)
    t = np.arange(len(run["u"])) * dt
    for k in range(2):
        ax_u = fig.add_subplot(1, 3, k + 2)
        ax_u.plot(t, reference.u_true[:, k], "k--", lw=1.2, label="true")
        ax_u.plot(t, run["u"][:, k], lw=0.9, label="reconstructed")
        ax_u.set(xlabel="t [s]", ylabel=f"$u_{k + 1}$ [N]")
    ax_u.legend(fontsize=7)
    fig.tight_layout()
    return fig


def uncertainty(spread, error, families, burst_time, burst_spread, burst_error):
    """Left: mean actuation spread over noise draws against tracking RMSE, one dot per
    reference, coloured by family. Right: spread and tip error over the burst circle."""
    fig, (ax, ax2) = plt.subplots(1, 2, figsize=(10, 3.8))
    for k, family in enumerate(dict.fromkeys(families)):
        chosen = np.asarray(families) == family
        ax.scatter(np.asarray(spread)[chosen], np.asarray(error)[chosen], s=18, color=f"C{k}", label=family)
    ax.set(xscale="log", yscale="log", xlabel="actuation spread over noise draws [N]", ylabel="tracking RMSE [mm]")
    ax.legend(fontsize=8)
    ax2.plot(burst_time, burst_spread, color="C0")
    ax2.set(xlabel="t [s]", ylabel="actuation spread [N]")
    ax2.yaxis.label.set_color("C0")
    twin = ax2.twinx()
    twin.plot(burst_time, np.asarray(burst_error) * MM, color="C3", lw=0.8)
    twin.set_ylabel("tip error [mm]", color="C3")
    twin.grid(False)
    return fig


def twin_tracking(runs: dict, references: dict, names, dt: float):
    """Camera-measured y-z tracking on the hardware twin: rows are configurations, columns
    shapes; the reference dashed, the camera track solid, Initial (diamond) and Start (dot)."""
    fig, axes = plt.subplots(len(runs), len(names), figsize=(3.3 * len(names), 3.3 * len(runs)), squeeze=False)
    for row, (config, config_runs) in enumerate(runs.items()):
        for ax, name in zip(axes[row], names):
            r, run = references[config][name], config_runs[name]
            scored = r.mask[np.round(run["frame_times"] / dt).astype(int)]
            ax.plot(r.states[r.mask, 1] * MM, r.states[r.mask, 2] * MM, "k--", lw=1.2, label="reference")
            ax.plot(run["tracked"][scored, 1] * MM, run["tracked"][scored, 2] * MM, lw=1, label="camera")
            start = np.argmax(r.mask)
            ax.plot(r.states[0, 1] * MM, r.states[0, 2] * MM, "kD", mfc="none", label="Initial")
            ax.plot(r.states[start, 1] * MM, r.states[start, 2] * MM, "ko", label="Start")
            ax.set(title=f"{name} ({config})", xlabel="y [mm]", ylabel="z [mm]", aspect="equal")
    axes[0, -1].legend(fontsize=7)
    fig.tight_layout()
    return fig


def images(pictures: dict, columns: int = 2):
    """BGR images (OpenCV order) in a grid, titled by their keys."""
    rows = -(-len(pictures) // columns)
    fig, axes = plt.subplots(rows, columns, figsize=(3.8 * columns, 3.0 * rows), squeeze=False)
    for ax in axes.flat:
        ax.axis("off")
    for ax, (title, picture) in zip(axes.flat, pictures.items()):
        ax.imshow(picture[..., ::-1])
        ax.set_title(title)
    fig.tight_layout()
    return fig


def intervals(summaries: dict, labels: dict, xlabel: str = "RMSE [mm]"):
    """One panel per title in ``summaries`` ({title: DataFrame indexed by model with mean, low,
    high}): each model's mean and interval, on a log axis (the floor sits far below)."""
    fig, axes = plt.subplots(1, len(summaries), figsize=(4.2 * len(summaries), 3.2), sharey=True)
    for ax, (title, table) in zip(np.atleast_1d(axes), summaries.items()):
        y = np.arange(len(table))[::-1]
        ax.errorbar(
            table["mean"],
            y,
            xerr=[table["mean"] - table["low"], table["high"] - table["mean"]],
            fmt="o",
            color="k",
            capsize=3,
        )
        ax.set(xscale="log", xlabel=xlabel, title=title, yticks=y, yticklabels=[labels.get(m, m) for m in table.index])
    fig.tight_layout()
    return fig


def condition_grid(table, labels: dict, title: str):
    """A condition x model table of RMSE (mm) as a heatmap on a log colour scale, values written in."""
    from matplotlib.colors import LogNorm

    values = table.to_numpy(float)
    fig, ax = plt.subplots(figsize=(1.1 * values.shape[1] + 2.5, 0.38 * values.shape[0] + 1.4))
    image = ax.imshow(values, norm=LogNorm(np.nanmin(values), np.nanmax(values)), cmap="viridis", aspect="auto")
    for (i, j), v in np.ndenumerate(values):
        if np.isfinite(v):
            ax.text(
                j, i, f"{v:.2g}", ha="center", va="center", fontsize=7, color="w" if v < np.nanmax(values) / 3 else "k"
            )
    ax.set(
        xticks=range(values.shape[1]),
        xticklabels=[labels.get(m, m) for m in table.columns],
        yticks=range(values.shape[0]),
        yticklabels=table.index,
        title=title,
    )
    ax.tick_params(axis="x", rotation=30)
    ax.grid(False)
    fig.colorbar(image, ax=ax, label="RMSE [mm]")
    return fig


def band_lines(ax, summary, x: str, by: str, label=str):
    """One line of ``mean`` against column ``x`` per group of ``by``, with its interval
    (``low``..``high``) as a band: the studies' curves with their 95 % intervals."""
    for group, part in summary.groupby(by, sort=False):
        (line,) = ax.plot(part[x], part["mean"], "o-", ms=3, label=label(group))
        ax.fill_between(part[x], part["low"], part["high"], color=line.get_color(), alpha=0.15)


def against_speed(summary, coverage, labels: dict):
    """RMSE against the shapes' mean tip speed per model, with interval bands, and the
    references' coverage by the training states on a second axis."""
    fig, ax = plt.subplots()
    band_lines(ax, summary, "speed", "model", lambda model: labels.get(model, model))
    ax.set(xlabel="mean tip speed of the shapes [m/s]", ylabel="RMSE [mm]", yscale="log")
    twin = ax.twinx()
    twin.plot(coverage.index, coverage.values, "k--", lw=1)
    twin.set(ylabel="coverage by training states (dashed)", ylim=(0, 1.05))
    twin.grid(False)
    ax.legend(fontsize=7, ncol=2)
    return fig


def latency_curve(closed, open_loop):
    """Closed-loop RMSE (mean over the shapes, mm) against camera latency, one line per
    configuration (``closed``: indexed by latency in s, columns configurations), with the
    open loop (dashed, ``open_loop``: configuration -> mm) for comparison."""
    fig, ax = plt.subplots(figsize=(5.2, 3.6))
    for config in closed.columns:
        (line,) = ax.plot(closed.index * MM, closed[config], "o-", label=f"closed, {config}")
        ax.axhline(open_loop[config], color=line.get_color(), ls="--", lw=1, label=f"open, {config}")
    ax.set(xlabel="camera latency [ms]", ylabel="RMSE, mean of the shapes [mm]", ylim=(0, None))
    ax.legend(fontsize=7)
    return fig


def identified_terms(identified):
    """Identified reality-gap terms against the truth (``identified``: rows E, eta, rho
    (relative) and motor_lag (s); columns the truth and each configuration's fit)."""
    relative, lag = identified.drop(index="motor_lag"), identified.loc["motor_lag"]
    fig, (ax, ax_lag) = plt.subplots(1, 2, figsize=(7.5, 3.2), gridspec_kw=dict(width_ratios=(3, 1)))
    width = 0.8 / len(identified.columns)
    for k, column in enumerate(identified.columns):
        style = dict(color="k" if column == "truth" else f"C{k}", label=column, width=width)
        ax.bar(np.arange(len(relative)) + k * width, 100 * relative[column], **style)
        ax_lag.bar(k * width, MM * lag[column], **style)
    ax.set(
        xticks=np.arange(len(relative)) + width * (len(identified.columns) - 1) / 2,
        xticklabels=relative.index,
        ylabel="error against the model rod [%]",
    )
    ax.axhline(0, color="k", lw=0.8)
    ax_lag.set(xticks=[], xlabel="motor lag", ylabel="[ms]")
    ax.legend(fontsize=7)
    fig.tight_layout()
    return fig


def against_data_size(summary, labels: dict):
    """Tracking RMSE against the training episodes per model, with interval bands, one panel
    per reference family (``summary``: model, episodes, family, mean, low, high)."""
    families = list(dict.fromkeys(summary["family"]))
    fig, axes = plt.subplots(1, len(families), figsize=(4.6 * len(families), 3.6), squeeze=False)
    for ax, family in zip(axes[0], families):
        band_lines(
            ax, summary[summary["family"] == family], "episodes", "model", lambda model: labels.get(model, model)
        )
        ax.set(xscale="log", yscale="log", xlabel="training episodes", ylabel="RMSE [mm]", title=f"{family} references")
        for formatter in (ax.yaxis.set_major_formatter, ax.yaxis.set_minor_formatter):  # 0.6, not 6 x 10^-1
            formatter(FuncFormatter(lambda value, _: f"{value:g}"))
        sizes = sorted(set(summary["episodes"]))
        ax.set_xticks(sizes, [f"{size:g}" for size in sizes], minor=False)
        ax.xaxis.set_minor_formatter(FuncFormatter(lambda *_: ""))
    axes[0, 0].legend(fontsize=7)
    fig.tight_layout()
    return fig


def ambiguity_panel(per_step, labels: dict):
    """Per dataset variant: each model's per-step u error (bars) beside the data's conditional
    spread and its floor (per input, markers); and the flows' draw spread against their error
    (Spearman correlation per transition). ``per_step``: indexed by (variant, model)."""
    variants = list(dict.fromkeys(per_step.index.get_level_values("variant")))
    models = list(dict.fromkeys(per_step.index.get_level_values("model")))
    fig, (ax, ax_rank) = plt.subplots(1, 2, figsize=(11, 3.8), gridspec_kw=dict(width_ratios=(2, 1)))
    width, x = 0.8 / len(models), np.arange(len(variants))
    for k, model in enumerate(models):
        part = per_step.xs(model, level="model").reindex(variants)
        ax.bar(x + k * width, part["u_rmse_test"], width, label=labels.get(model, model))
        if "spread_error_spearman" in part and part["spread_error_spearman"].notna().any():
            ax_rank.bar(
                x + k * width, part["spread_error_spearman"], width, color=f"C{k}", label=labels.get(model, model)
            )
    first = per_step.groupby(level="variant", sort=False).first().reindex(variants)
    centre = x + width * (len(models) - 1) / 2
    ax.plot(centre, first["conditional_spread"] / np.sqrt(2), "k_", ms=18, mew=2, label="conditional spread")
    ax.plot(
        centre, first["conditional_spread_floor"] / np.sqrt(2), "k_", ms=18, mew=1, alpha=0.4, label="estimator floor"
    )
    for a in (ax, ax_rank):
        a.set_xticks(centre, variants, rotation=30, ha="right")
    ax.set(ylabel="per-step u error, RMS per input [N]", yscale="log")
    ax_rank.set(ylabel="Spearman(draw spread, error)", ylim=(-0.2, 1))
    ax_rank.axhline(0, color="k", lw=0.8)
    ax.legend(fontsize=7)
    fig.tight_layout()
    return fig


def regime_map(table, labels: dict):
    """Flow minus MLP (z = 0 plans) against the measured ambiguity (conditional spread over its
    estimator floor), one point per variant and flow: tracking RMSE (mm, per family) and the
    per-step u error (N), with 95 % intervals; below zero the flow wins."""
    fig, (ax, ax_step) = plt.subplots(1, 2, figsize=(11, 4))
    ambiguity = table["conditional_spread"] / table["spread_floor"]
    markers = {flow: m for flow, m in zip(dict.fromkeys(table.index.get_level_values("flow")), "os^")}
    for (variant, flow), level in ambiguity.items():
        row = table.loc[(variant, flow)]
        for k, family in enumerate(("shape", "random")):
            ax.errorbar(
                level,
                row[f"{family}_mm"],
                [[row[f"{family}_mm"] - row[f"{family}_low"]], [row[f"{family}_high"] - row[f"{family}_mm"]]],
                fmt=markers[flow],
                color=f"C{k}",
                capsize=3,
            )
        step_error = [[row.step_N - row.step_low], [row.step_high - row.step_N]] if np.isfinite(row.step_low) else None
        ax_step.errorbar(level, row.step_N, step_error, fmt=markers[flow], color="k", capsize=3)
        for a, y in ((ax, row["random_mm"]), (ax_step, row.step_N)):
            a.annotate(variant, (level, y), fontsize=6, xytext=(3, 3), textcoords="offset points")
    for k, family in enumerate(("shape", "random")):
        ax.plot([], [], "o", color=f"C{k}", label=f"{family} references")
    for flow, m in markers.items():
        ax.plot([], [], m, color="gray", label=f"{labels.get(flow, flow)} - MLP")
    for a, unit in ((ax, "tracking RMSE [mm]"), (ax_step, "per-step u error [N]")):
        a.axhline(0, color="k", lw=0.8)
        a.set(xlabel="conditional spread / estimator floor (1: none measurable)", ylabel=f"flow - MLP, {unit}")
    ax.set_yscale("symlog", linthresh=1.0)  # tenths of a mm and tens of mm on one axis; linear within 1 mm
    ax.yaxis.set_major_formatter(FuncFormatter(lambda value, _: f"{value:g}"))
    ax.legend(fontsize=7)
    fig.tight_layout()
    return fig


def consistency_weight(summary, diagnostics, taus):
    """RF-FWD's consistency weight: tracking RMSE against lambda per family with interval bands
    (``summary``: consistency, family, mean, low, high); and, per lambda, the u error of the
    loss's one-step endpoint estimate (solid) and of a short Euler rollout (dashed) against tau
    (``diagnostics``: indexed by lambda, columns one_step_u_error_tau<t>, euler_u_error_tau<t>)."""
    fig, (ax, ax_tau) = plt.subplots(1, 2, figsize=(10, 3.6))
    band_lines(ax, summary, "consistency", "family", lambda family: f"{family} references")
    ax.set_xscale("symlog", linthresh=0.03)  # lambda = 0 (RF) on the same axis as 0.03-1
    ax.set(
        xlabel="consistency weight lambda",
        ylabel="RMSE [mm]",
        yscale="log",
        xlim=(0, 1.2 * summary["consistency"].max()),
    )
    ax.legend(fontsize=7)
    for k, (weight, row) in enumerate(diagnostics.iterrows()):
        for label, style in (("one_step", "-"), ("euler", "--")):
            ax_tau.plot(
                taus,
                [row[f"{label}_u_error_tau{t:g}"] for t in taus],
                style,
                color=f"C{k}",
                label=f"lambda = {weight:g}" if label == "one_step" else None,
            )
    ax_tau.set(xlabel="tau", ylabel="endpoint u error [N] (solid: one step, dashed: Euler)")
    ax_tau.legend(fontsize=7)
    fig.tight_layout()
    return fig
