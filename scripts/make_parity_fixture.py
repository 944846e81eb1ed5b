"""Make the MobileNetV2 parity fixture for grasp-model/tests/it/model_parity.rs.

Builds torchvision's mobilenet_v2 at a reduced width with seeded random
weights and realistic batch-norm statistics, and saves into
grasp-model/tests/fixtures/:
  mnv2_w010.pth          state_dict, PyTorch zip format (torch.save)
  mnv2_w010.safetensors  the same state_dict
  mnv2_w010_io.safetensors
      input            (2, 3, 45, 45) normalized input (odd size on purpose)
      features         eval-mode pooled features
      logits           eval-mode logits
      train_features   train-mode pooled features (batch statistics)
      train_running_mean / train_running_var
                       features.1.conv.0.1 running stats after that pass
  mnv2_w010_legacy.pth   a few of the tensors in PyTorch's legacy (pre-1.6)
                         format, the format of torchvision's
                         mobilenet_v2-b0353104.pth

Needs the benchmark environment with torch and torchvision (CI does not run
this):
  P=$(lab/bench-env.sh | tail -n1)
  $P scripts/make_parity_fixture.py
"""

import copy
import pathlib

import torch
import torchvision
from safetensors.torch import save_file

WIDTH = 0.1
CLASSES = 5
SIZE = 45
BATCH = 2
SEED = 1234
LEGACY_KEYS = [
    "features.0.0.weight",
    "features.0.1.running_var",
    "features.0.1.num_batches_tracked",
    "features.2.conv.1.0.weight",
    "classifier.1.bias",
]
OUT = pathlib.Path(__file__).resolve().parent.parent / "grasp-model" / "tests" / "fixtures"


def build() -> torch.nn.Module:
    torch.manual_seed(SEED)
    model = torchvision.models.mobilenet_v2(weights=None, width_mult=WIDTH, num_classes=CLASSES)
    # Random affine batch-norm parameters, then running statistics gathered
    # from a few train-mode passes (cumulative average), so that eval-mode
    # activations have sensible scales instead of saturating ReLU6.
    for m in model.modules():
        if isinstance(m, torch.nn.BatchNorm2d):
            with torch.no_grad():
                m.weight.uniform_(0.5, 1.5)
                m.bias.normal_(0.0, 0.2)
            m.momentum = None
            m.reset_running_stats()
        if isinstance(m, torch.nn.Linear):
            with torch.no_grad():
                m.weight.normal_(0.0, 0.1)
                m.bias.normal_(0.0, 0.1)
    model.train()
    with torch.no_grad():
        for _ in range(4):
            model(torch.randn(8, 3, SIZE, SIZE))
    for m in model.modules():
        if isinstance(m, torch.nn.BatchNorm2d):
            m.momentum = 0.1
    return model.eval()


def pooled(model: torch.nn.Module, x: torch.Tensor) -> torch.Tensor:
    return model.features(x).mean(dim=(2, 3))


def main() -> None:
    model = build()
    x = torch.randn(BATCH, 3, SIZE, SIZE, generator=torch.Generator().manual_seed(SEED + 1))
    with torch.no_grad():
        features = pooled(model, x)
        logits = model(x)
        trained = copy.deepcopy(model).train()
        train_features = pooled(trained, x)
    bn = trained.features[1].conv[0][1]
    state = {k: v.contiguous() for k, v in model.state_dict().items()}
    OUT.mkdir(parents=True, exist_ok=True)
    torch.save(state, OUT / "mnv2_w010.pth")
    save_file(state, str(OUT / "mnv2_w010.safetensors"))
    legacy = {k: state[k] for k in LEGACY_KEYS}
    torch.save(legacy, OUT / "mnv2_w010_legacy.pth", _use_new_zipfile_serialization=False)
    io = {
        "input": x,
        "features": features,
        "logits": logits,
        "train_features": train_features,
        "train_running_mean": bn.running_mean.clone(),
        "train_running_var": bn.running_var.clone(),
    }
    save_file({k: v.contiguous() for k, v in io.items()}, str(OUT / "mnv2_w010_io.safetensors"))
    zeros = (features == 0).float().mean().item()
    print(f"features {tuple(features.shape)}: std {features.std():.3f}, zero fraction {zeros:.2f}")
    print(f"logits {logits.tolist()}")
    for f in sorted(OUT.glob("mnv2_w010*")):
        print(f"{f.name}: {f.stat().st_size / 1024:.0f} KiB")


if __name__ == "__main__":
    main()
