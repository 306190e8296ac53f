"""Pilot networks as stable-baselines3 policies, and RL policies as ordinary pilot model files.

The policy's actor *is* a pilot model: :class:`PilotTrunk`, the features extractor, holds the
model's convolutions and its hidden dense layers (built by :func:`parts.pilots.models.create_model`,
normalising frames as the model's preprocessing does); SB3's ``action_net`` (PPO) or ``mu`` (SAC)
is the model's last linear layer. The deterministic action is then exactly what the pilot model
computes (PPO: the Gaussian's mean; SAC: its tanh, the ``linear_tanh`` type), so
:func:`export_pilot` copies the weights into a model of that type and saves an ordinary model file
(weights and plain metadata only) that ``manage.py drive --model``, ``vehicle sim eval`` and the
ONNX/int8 exports take. :func:`load_pilot_weights` starts a policy from a behaviour-cloned pilot of
the same network.

With a throttle range (``TrackEnv(throttle_range=(low, high))``) the policy's throttle action a in
[-1, 1] drives the throttle ``mid + half * a`` (mid, half: the range's centre and half-width).
That affine map is folded into the throttle row of the last layer on export, and the model's
``throttle_limits`` clamps it to [low, high] as the environment does, so the file still drives
exactly the policy's deterministic action; starting from a pilot unfolds it.

This module imports stable-baselines3: import it only where RL runs.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import gymnasium as gym
import torch
from stable_baselines3.common.torch_layers import BaseFeaturesExtractor
from torch import nn

from parts.pilots.modelfile import save_model
from parts.pilots.models import PilotModel, create_model

#: pilot model types a policy can be, by (algorithm, steering only)
POLICY_TYPES: dict[tuple[str, bool], str] = {
    ("ppo", False): "linear", ("ppo", True): "inferred",
    ("sac", False): "linear_tanh",
}


def policy_model_type(algo: str, steering_only: bool) -> str:
    """The pilot model type a policy of ``algo`` exports to."""
    if algo.lower() not in ("ppo", "sac"):
        raise ValueError(f"unknown RL algorithm {algo!r}: use ppo or sac")
    if (algo.lower(), steering_only) not in POLICY_TYPES:
        raise ValueError("SAC learns steering and throttle: drop the fixed throttle, or use PPO for steering only")
    return POLICY_TYPES[(algo.lower(), steering_only)]


def model_options(model_type: str, throttle: float | None) -> dict[str, Any]:
    """Options of the pilot model type; dropout off (RL's updates need the same network that acted).
    A steering-only ``inferred`` policy drives at the fixed ``throttle`` (throttle_min = max)."""
    options: dict[str, Any] = {"dropout": 0.0}
    if model_type == "inferred":
        t = float(throttle if throttle is not None else 0.3)
        options.update(throttle_min=t, throttle_max=t)
    return options


class PilotTrunk(BaseFeaturesExtractor):
    """SB3 features extractor: a pilot model's CNN and hidden dense layers.

    Observations come channels-first (SB3 transposes uint8 images) as floats 0..255
    (``normalize_images=False``); they are normalised here as the pilot's preprocessing does.
    """

    def __init__(self, observation_space: gym.spaces.Box, model_type: str = "linear",
                 options: dict[str, Any] | None = None, normalize: str = "symmetric") -> None:
        c, h, w = (int(v) for v in observation_space.shape)
        model = create_model(model_type, (c, h, w), **(options or {}))
        last = model.head[-1]
        super().__init__(observation_space, last.in_features)
        if normalize not in ("unit", "symmetric"):
            raise ValueError(f"normalize must be 'unit' or 'symmetric', got {normalize!r}")
        self.model_type, self.options, self.normalize = model_type, dict(model.options), normalize
        self.input_shape = (c, h, w)
        self.n_actions = int(last.out_features)
        self.features = model.features
        self.hidden = model.head[:-1]

    def forward(self, obs: torch.Tensor) -> torch.Tensor:
        x = obs.float()
        # the same float32 operations as Preprocess.normalize_batch / Preprocess.array
        x = x * (1.0 / 255.0) if self.normalize == "unit" else x * (1.0 / 127.5) - 1.0
        return self.hidden(self.features(x))


def policy_kwargs(algo: str, model_type: str, options: dict[str, Any], normalize: str, *,
                  log_std_init: float = -0.5, share_trunk: bool = True) -> dict[str, Any]:
    """SB3 ``policy_kwargs`` that make the actor the pilot model (no extra actor layers).

    PPO: ``log_std_init`` is the log of the exploration noise's starting standard deviation (in
    action units); ``share_trunk=False`` gives the critic its own copy of the trunk, so that value
    updates cannot move the actor's features (fine-tuning a behaviour-cloned pilot).
    """
    trunk_options = {k: v for k, v in options.items() if k != "throttle_limits"}  # the export sets them
    kwargs: dict[str, Any] = {
        "features_extractor_class": PilotTrunk,
        "features_extractor_kwargs": {"model_type": model_type, "options": trunk_options, "normalize": normalize},
        "normalize_images": False,
    }
    if algo == "ppo":
        kwargs["net_arch"] = {"pi": [], "vf": [64]}
        kwargs["log_std_init"] = float(log_std_init)
        kwargs["share_features_extractor"] = bool(share_trunk)
    else:
        kwargs["net_arch"] = {"pi": [], "qf": [256, 256]}
    return kwargs


def _actor_parts(policy: Any) -> tuple[PilotTrunk, nn.Linear]:
    """The trunk and last layer of a PPO (ActorCriticPolicy) or SAC (SACPolicy) policy."""
    if hasattr(policy, "actor") and hasattr(policy.actor, "mu"):  # SAC
        return policy.actor.features_extractor, policy.actor.mu
    trunk = getattr(policy, "pi_features_extractor", None) or policy.features_extractor
    return trunk, policy.action_net


def _mid_half(throttle_range: tuple[float, float]) -> tuple[float, float]:
    low, high = throttle_range
    return (high + low) / 2.0, (high - low) / 2.0


def policy_model(policy: Any, throttle_range: tuple[float, float] | None = None) -> PilotModel:
    """The policy's actor as a pilot model (a copy of its weights, eval mode); with the
    environment's ``throttle_range``, the model drives the throttle that range makes of the action."""
    trunk, last = _actor_parts(policy)
    if not isinstance(trunk, PilotTrunk):
        raise TypeError("the policy was not built on a pilot model (policy_kwargs of training.rl)")
    options = dict(trunk.options)
    if throttle_range is not None:
        if trunk.n_actions != 2:
            raise ValueError("a throttle range needs a policy that drives the throttle (no fixed throttle)")
        options["throttle_limits"] = [float(v) for v in throttle_range]
    model = create_model(trunk.model_type, trunk.input_shape, **options)
    model.features.load_state_dict(trunk.features.state_dict())
    model.head[:-1].load_state_dict(trunk.hidden.state_dict())
    model.head[-1].load_state_dict(last.state_dict())
    if throttle_range is not None:
        mid, half = _mid_half(throttle_range)
        with torch.no_grad():  # throttle = mid + half * action
            model.head[-1].weight[1].mul_(half)
            model.head[-1].bias[1].mul_(half).add_(mid)
    return model.eval()


def export_pilot(policy: Any, path: str | os.PathLike[str], meta: dict[str, Any],
                 throttle_range: tuple[float, float] | None = None) -> Path:
    """Save the policy's actor as an ordinary pilot model file (``meta`` as training writes it:
    type, preprocess, training, camera ...); ``throttle_range`` as the environment's."""
    model = policy_model(policy, throttle_range)
    return save_model(path, model, {**meta, "type": model.type_name})


def load_pilot_weights(policy: Any, model: PilotModel, throttle_range: tuple[float, float] | None = None) -> None:
    """Start the policy's actor from a trained pilot of the same type and input shape; with the
    environment's ``throttle_range``, the action that drives the pilot's throttle (the inverse of
    :func:`policy_model`'s map; a throttle beyond the range becomes an action beyond [-1, 1],
    which the environment clips to the range's end, as the exported pilot's limits do).

    Raises:
        ValueError: the pilot's type or input shape differs from the policy's network.
    """
    trunk, last = _actor_parts(policy)
    if model.type_name != trunk.model_type or tuple(model.input_shape) != trunk.input_shape:
        raise ValueError(f"the pilot is a {model.type_name!r} model of input {tuple(model.input_shape)}; this policy "
                         f"is a {trunk.model_type!r} network of input {trunk.input_shape}")
    trunk.features.load_state_dict(model.features.state_dict())
    trunk.hidden.load_state_dict(model.head[:-1].state_dict())
    last.load_state_dict(model.head[-1].state_dict())
    if throttle_range is not None:
        mid, half = _mid_half(throttle_range)
        with torch.no_grad():  # action = (throttle - mid) / half
            last.weight[1].div_(half)
            last.bias[1].sub_(mid).div_(half)
    critic = getattr(policy, "vf_features_extractor", None)
    if isinstance(critic, PilotTrunk) and critic is not trunk:
        critic.load_state_dict(trunk.state_dict())


def actor_parameters(policy: Any) -> list[nn.Parameter]:
    """The parameters that make a PPO policy's actions: its trunk (shared with the critic unless
    ``share_trunk=False``), the action layer and the exploration noise's log std."""
    trunk, last = _actor_parts(policy)
    params = [*trunk.parameters(), *last.parameters()]
    log_std = getattr(policy, "log_std", None)
    return params + ([log_std] if isinstance(log_std, nn.Parameter) else [])


def freeze_actor(policy: Any, frozen: bool) -> None:
    """Freeze (or free) the actor: while frozen only the critic learns (value-function warm-up
    before a behaviour-cloned actor is fine-tuned; the optimiser skips parameters without grads)."""
    for p in actor_parameters(policy):
        p.requires_grad_(not frozen)
