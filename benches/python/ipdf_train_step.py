"""Baseline for the `train_step/*` criterion benches: the same Implicit-PDF training step in PyTorch.

Mirrors `ipdf_model::Trainer::train_step` with `TrainOptions::default()` minus augmentation:
- crops [B, 3, S, S] in [0, 1], ImageNet-normalised, through a small CNN (4 × conv3x3/2 + BN + ReLU,
  32–256 channels, global pooling) or ResNet-18 without its classifier (written out here, same
  layers as torchvision's);
- queries: a fixed set of N = 4,608 rotations left-multiplied by one random rotation per step,
  then right-multiplied per image so that query 0 equals the image's label;
- positional encoding sin/cos(2^k r), k < 3, of the flattened matrices (54-d); head: image and
  query linear layers (→ 256) summed, ReLU, 3 × (256 → 256, ReLU), 256 → 1;
- loss −(F(label) − logsumexp F(queries) + ln(N/π²)); Adam (lr 1e-4), gradient norm clipped to 5.

Prints seconds per step and images/s per encoder, on the torch the venv holds (2.11.0, the
same libtorch the Rust crate links), on the CPU or `--device cuda`. Run: `make bench-python`.
"""
import argparse
import json
import math
import time

import torch
from torch import nn


def conv_bn(c_in, c_out, kernel, stride):
    return nn.Sequential(
        nn.Conv2d(c_in, c_out, kernel, stride, kernel // 2, bias=False), nn.BatchNorm2d(c_out)
    )


class BasicBlock(nn.Module):
    def __init__(self, c_in, c_out, stride):
        super().__init__()
        self.a = conv_bn(c_in, c_out, 3, stride)
        self.b = conv_bn(c_out, c_out, 3, 1)
        self.down = conv_bn(c_in, c_out, 1, stride) if stride != 1 or c_in != c_out else None

    def forward(self, x):
        y = self.b(torch.relu(self.a(x)))
        return torch.relu(y + (x if self.down is None else self.down(x)))


def resnet18():
    layers = [conv_bn(3, 64, 7, 2), nn.ReLU(), nn.MaxPool2d(3, 2, 1)]
    for c_in, c_out, stride in [(64, 64, 1), (64, 128, 2), (128, 256, 2), (256, 512, 2)]:
        layers += [BasicBlock(c_in, c_out, stride), BasicBlock(c_out, c_out, 1)]
    return nn.Sequential(*layers, nn.AdaptiveAvgPool2d(1), nn.Flatten()), 512


def small_cnn():
    layers = []
    for c_in, c_out in [(3, 32), (32, 64), (64, 128), (128, 256)]:
        layers += [conv_bn(c_in, c_out, 3, 2), nn.ReLU()]
    return nn.Sequential(*layers, nn.AdaptiveAvgPool2d(1), nn.Flatten()), 256


class ImplicitPdf(nn.Module):
    def __init__(self, encoder, width=256, depth=4, fourier=3):
        super().__init__()
        self.encoder, features = {"small-cnn": small_cnn, "resnet18": resnet18}[encoder]()
        self.fourier = fourier
        self.image = nn.Linear(features, width)
        self.query = nn.Linear(18 * fourier, width)
        self.hidden = nn.ModuleList(nn.Linear(width, width) for _ in range(depth - 1))
        self.out = nn.Linear(width, 1)
        self.register_buffer("mean", torch.tensor([0.485, 0.456, 0.406]).view(1, 3, 1, 1))
        self.register_buffer("std", torch.tensor([0.229, 0.224, 0.225]).view(1, 3, 1, 1))

    def forward(self, images, rotations):
        image_term = self.image(self.encoder((images - self.mean) / self.std)).unsqueeze(1)
        encoded = torch.cat(
            [f(rotations * 2.0**k) for k in range(self.fourier) for f in (torch.sin, torch.cos)], -1
        )
        x = torch.relu(image_term + self.query(encoded))
        for layer in self.hidden:
            x = torch.relu(layer(x))
        return self.out(x).squeeze(-1)


def random_rotations(n, generator):
    q = torch.randn(n, 4, generator=generator)
    w, x, y, z = (q / q.norm(dim=1, keepdim=True)).unbind(1)
    return torch.stack(
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w),
         2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w),
         2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], 1
    ).view(n, 3, 3)


def run(encoder, batch, size, queries, steps, warmup, device="cpu"):
    generator = torch.Generator().manual_seed(0)
    model = ImplicitPdf(encoder).to(device)
    optimiser = torch.optim.Adam(model.parameters(), lr=1e-4)
    images = torch.rand(batch, 3, size, size, generator=generator).to(device)
    labels = random_rotations(batch, generator).to(device)
    grid = random_rotations(queries, generator).to(device)
    log_volume = math.log(queries / math.pi**2)

    def step():
        turned = random_rotations(1, generator)[0].to(device) @ grid
        shift = turned[0].T @ labels
        rotations = (turned.unsqueeze(0) @ shift.unsqueeze(1)).reshape(batch, queries, 9)
        scores = model(images, rotations)
        loss = -(scores[:, 0] - torch.logsumexp(scores, 1) + log_volume).mean()
        optimiser.zero_grad()
        loss.backward()
        torch.nn.utils.clip_grad_norm_(model.parameters(), 5.0)
        optimiser.step()

    def synchronise():
        if device.startswith("cuda"):
            torch.cuda.synchronize()

    for _ in range(warmup):
        step()
    synchronise()
    started = time.perf_counter()
    for _ in range(steps):
        step()
    synchronise()
    seconds = (time.perf_counter() - started) / steps
    print(f"pytorch {encoder} {size}px batch {batch} on {device}: {seconds:.3f} s/step, "
          f"{batch / seconds:.1f} images/s")
    return {"encoder": encoder, "batch": batch, "size": size, "queries": queries,
            "steps": steps, "seconds_per_step": seconds, "images_per_second": batch / seconds,
            "device": device, "torch_version": torch.__version__,
            "threads": torch.get_num_threads()}


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--encoder", choices=["small-cnn", "resnet18"])
    parser.add_argument("--batch", type=int, default=32)
    parser.add_argument("--size", type=int, default=96)
    parser.add_argument("--queries", type=int, default=4608)
    parser.add_argument("--steps", type=int, default=10)
    parser.add_argument("--warmup", type=int, default=2)
    parser.add_argument("--device", default="cpu", help="cpu, or cuda on a GPU machine")
    parser.add_argument("--json")
    args = parser.parse_args()
    encoders = [args.encoder] if args.encoder else ["small-cnn", "resnet18"]
    results = [run(e, args.batch, args.size, args.queries, args.steps, args.warmup, args.device)
               for e in encoders]
    if args.json:
        with open(args.json, "w") as f:
            json.dump(results, f, indent=1)


if __name__ == "__main__":
    main()
