"""The checkpoint of a training run: its two files, written atomically every epoch, and read back on resume.

``checkpoint.safetensors`` holds the weights, the best weights, the optimizer's state and torch's
generator state; ``checkpoint.json`` the epoch, history, counters and the run's fingerprint (what
they hold and why: ``train.py``). Apart from the loop because the file format is its own concern:
the loop only saves where it stands and, on a restart, gets it back or nothing.
"""
from __future__ import annotations

import json
import os
from pathlib import Path

import torch
from safetensors import safe_open
from safetensors.torch import save_file

from .model_file import ModelError


def _optimizer_tensors(opt: torch.optim.Optimizer) -> tuple[dict, dict]:
    sd = opt.state_dict()
    tensors = {}
    for pid, st in sd["state"].items():
        for k, v in st.items():
            tensors[f"opt.{pid}.{k}"] = torch.as_tensor(v).detach().cpu().contiguous()
    return tensors, {"param_groups": sd["param_groups"]}


def _restore_optimizer(opt: torch.optim.Optimizer, tensors: dict, meta: dict) -> None:
    state: dict = {}
    for key, v in tensors.items():
        _, pid, k = key.split(".", 2)
        state.setdefault(int(pid), {})[k] = v
    opt.load_state_dict({"state": state, "param_groups": meta["param_groups"]})


def _save_checkpoint(out_dir: Path, module, best_state, opt, info: dict) -> None:
    tensors = {f"model.{k}": v.detach().cpu().contiguous() for k, v in module.state_dict().items()}
    tensors.update({f"best.{k}": v.detach().cpu().contiguous() for k, v in best_state.items()})
    opt_tensors, opt_meta = _optimizer_tensors(opt)
    tensors.update(opt_tensors)
    # Dropout draws its masks from torch's global generator: its state is part of
    # where training stands, or a resumed run drops other units than a straight one.
    tensors["rng.cpu"] = torch.get_rng_state()
    device = next(module.buffers()).device
    if device.type == "cuda":
        tensors["rng.cuda"] = torch.cuda.get_rng_state(device).cpu()
    info = dict(info, optimizer=opt_meta)
    tmp = out_dir / "checkpoint.safetensors.partial"
    save_file(tensors, str(tmp), metadata={"fingerprint": info["fingerprint"], "epoch": str(info["epoch"])})
    jtmp = out_dir / "checkpoint.json.partial"
    jtmp.write_text(json.dumps(info, indent=1))
    os.replace(tmp, out_dir / "checkpoint.safetensors")
    os.replace(jtmp, out_dir / "checkpoint.json")


def _load_checkpoint(out_dir: Path, fingerprint: str):
    jpath, tpath = out_dir / "checkpoint.json", out_dir / "checkpoint.safetensors"
    if not jpath.is_file() or not tpath.is_file():
        return None
    try:
        info = json.loads(jpath.read_text())
        with safe_open(str(tpath), framework="pt") as f:
            meta = f.metadata() or {}
            tensors = {k: f.get_tensor(k) for k in f.keys()}
    except Exception:  # a checkpoint torn by a kill is discarded: the run restarts cleanly
        return None
    if info.get("fingerprint") != fingerprint:
        raise ModelError(f"{out_dir} holds a checkpoint of another run (other preset, config or data); "
                         "choose another --out or delete it")
    if meta.get("fingerprint") != fingerprint or meta.get("epoch") != str(info["epoch"]):
        return None  # the two files are from different epochs (killed between the renames)
    return info, tensors
