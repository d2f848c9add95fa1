"""The studies' shared measurements (``softflow.studies``), on the small test dataset."""

from dataclasses import replace

import numpy as np
import torch

from softflow import control, studies


def test_held_out_error_is_measured_beyond_the_workspace_and_leaves_the_controller_checking(dataset, trained):
    controller = control.Controller(trained("mlp")[0], "mlp")
    far = dataset.states.copy()
    far[dataset.test, :, 0] += 1.0  # held-out episodes a metre off in x: extrapolation, measured
    shifted = replace(dataset, states=far)

    planned, error = studies.held_out_plan(controller, shifted)

    assert planned.shape == dataset.u[dataset.test].shape and np.isfinite(planned).all()
    assert np.abs(planned).max() <= controller.u_limit  # the clipped plan is judged
    by_hand = np.sqrt(np.mean([np.mean((p - u) ** 2) for p, u in zip(planned, dataset.u[dataset.test])]))
    np.testing.assert_allclose(error, by_hand, rtol=1e-12)
    assert controller.workspace_margin == control.WORKSPACE_MARGIN  # the user's controller still refuses them
    np.testing.assert_array_equal(
        studies.held_out_plan(controller, dataset)[0], controller.plan(dataset.states[dataset.test])
    )


def test_the_consistency_floor_is_the_surrogates_own_error_at_the_true_u(dataset, trained):
    forward, _ = trained("forward")
    floor = studies.fwd_lambda.consistency_floor(forward, dataset, points=500)

    x, x_next, u = studies.fwd_lambda._diagnostic_transitions(dataset, 500, np.random.default_rng(0))
    assert len(x) == 500
    with torch.inference_mode():
        loss = forward.compute_loss(torch.stack([x, x_next], 1), u)
        wrong = forward.increment(x, u + 0.5) - forward.delta_norm.normalize(x_next - x)
    np.testing.assert_allclose(floor, np.sqrt(float(loss)), rtol=1e-5)
    assert floor < float(torch.sqrt(torch.mean(wrong**2)))  # a wrong u misses by more than the surrogate does
