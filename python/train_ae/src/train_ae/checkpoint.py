"""Checkpoints: ``{"format", "config", "state_dict", "metrics"}`` of plain types and tensors.

No pickled classes, so ``torch.load(path, weights_only=True)`` (the default since torch 2.6)
reads them, and so does any later torch. Written to a temporary file, then renamed.

Example::

    save_checkpoint("ae.pt", model, {"heldout": {"n": 20, "correct": 17}})
    model, ckpt = load_checkpoint("ae.pt")      # model in eval mode
"""

from __future__ import annotations

import os
from pathlib import Path

import torch

from .model import GraspAutoencoder, ModelConfig

FORMAT = "lgdm.train_ae.v1"
"""Value of the checkpoint's ``format`` key."""


def save_checkpoint(path: str | Path, model: GraspAutoencoder, metrics: dict) -> None:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    state = {k: v.detach().clone().contiguous() for k, v in model.state_dict().items()}
    payload = {
        "format": FORMAT,
        "config": model.config.to_dict(),
        "state_dict": state,
        "metrics": metrics,
    }
    tmp = path.with_name(path.name + ".tmp")
    try:
        torch.save(payload, tmp)
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()


def load_checkpoint(path: str | Path) -> tuple[GraspAutoencoder, dict]:
    """(model in eval mode on the CPU, the whole checkpoint dict)."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"checkpoint {path} does not exist")
    try:
        ckpt = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as e:  # torch raises several types for corrupt or foreign files
        raise ValueError(f"{path}: not a readable train_ae checkpoint: {e}") from e
    if not isinstance(ckpt, dict) or ckpt.get("format") != FORMAT:
        raise ValueError(f"{path}: not a train_ae checkpoint (format key is not {FORMAT!r})")
    config = ModelConfig.from_dict(ckpt["config"])
    model = GraspAutoencoder(config)
    model.load_state_dict(ckpt["state_dict"])
    model.eval()
    return model, ckpt
