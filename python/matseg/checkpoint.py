"""A run's resume checkpoint, `checkpoint.safetensors`, in `matseg train`'s
layout, so that each trainer resumes the other's runs: `model.NAME` (every
variable of the net), `optim.m.NAME` and `optim.v.NAME` (AdamW's first and
second moments of each parameter), `optim.steps` (updates taken),
`next_step` (the next step to train) and `next_batch` (the next batch of
the stream: next_step times the processes that trained; absent in
`matseg train`'s, which trains one batch a step)."""

from . import _requires

_requires.torch("matseg.checkpoint")

import os
from typing import Any

import numpy as np
import torch
from numpy.typing import NDArray

from . import net as netlib
from . import tensor_files

CHECKPOINT_FILE = netlib.CONSTANTS["checkpoint_file"]
# The tensors' names, as `matseg train` writes and reads them.
_KEYS = netlib.CONSTANTS["checkpoint_keys"]
_MODEL, _OPTIM = _KEYS["model"], _KEYS["optimizer"]
_MOMENTS = ((_KEYS["first_moment"], "exp_avg"), (_KEYS["second_moment"], "exp_avg_sq"))
_STEPS = _OPTIM + _KEYS["optimizer_steps"]
_NEXT_STEP, _NEXT_BATCH = _KEYS["next_step"], _KEYS["next_batch"]


def write(folder: str | os.PathLike[str], arrays: dict[str, NDArray[Any]], net: torch.nn.Module,
          optimizer: torch.optim.Optimizer, updates: int, next_step: int, next_batch: int) -> None:
    """Writes `folder/checkpoint.safetensors` (through a temporary file):
    `arrays`, the net's `state_arrays`, and the optimizer's state of the
    net's parameters."""
    tensors = {_MODEL + k: v for k, v in arrays.items()}
    for name, p in net.named_parameters():
        state = optimizer.state.get(p, {})
        for key, moment in _MOMENTS:
            t = state.get(moment)
            value = np.zeros(tuple(p.shape), np.float32) if t is None else t.detach().to("cpu", torch.float32).numpy()
            tensors[_OPTIM + key + name] = value
    tensors[_STEPS] = np.array([updates], np.int64)
    tensors[_NEXT_STEP] = np.array([next_step], np.int64)
    tensors[_NEXT_BATCH] = np.array([next_batch], np.int64)
    tensor_files.write(os.path.join(folder, CHECKPOINT_FILE), tensors)


def read(folder: str | os.PathLike[str], net: torch.nn.Module,
         optimizer: torch.optim.Optimizer) -> tuple[int, int, int]:
    """Loads `folder/checkpoint.safetensors` into `net` and the AdamW
    `optimizer` over its parameters; returns (updates, next_step,
    next_batch). Errors name the file and what is missing or misshapen."""
    path = os.path.join(folder, CHECKPOINT_FILE)
    if not os.path.isfile(path):
        raise FileNotFoundError(f"{path}: no such file: the run has no checkpoint to resume from")
    tensors, _ = tensor_files.read(path)

    def scalar(key: str) -> int:
        if key not in tensors or tensors[key].size != 1:
            raise ValueError(f"{path}: no {key}")
        return int(tensors[key].reshape(-1)[0])

    updates, next_step = scalar(_STEPS), scalar(_NEXT_STEP)
    next_batch = scalar(_NEXT_BATCH) if _NEXT_BATCH in tensors else next_step
    netlib.load_arrays(net, {k[len(_MODEL):]: v for k, v in tensors.items() if k.startswith(_MODEL)}, path)
    for name, p in net.named_parameters():
        moments: dict[str, Any] = {}
        for key, moment in _MOMENTS:
            value = tensors.get(_OPTIM + key + name)
            if value is None:
                raise ValueError(f"{path}: optimizer state has no {key}{name}")
            if tuple(value.shape) != tuple(p.shape):
                raise ValueError(f"{path}: optimizer state {key}{name} is {tuple(value.shape)}, "
                                 f"the net's {tuple(p.shape)}")
            moments[moment] = torch.from_numpy(value).to(p.device, torch.float32)
        optimizer.state[p] = {"step": torch.tensor(float(updates), dtype=torch.float32), **moments}
    return updates, next_step, next_batch
