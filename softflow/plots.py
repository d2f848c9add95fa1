"""Every figure of the notebooks: one function per figure type, data in, Figure out.

Lengths arrive in SI units and are drawn in mm.
"""
from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np

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
