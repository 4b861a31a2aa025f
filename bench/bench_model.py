"""Training throughput of the decoder f against a plain `torch.nn.TransformerEncoder`.

    .venv/bin/python bench/bench_model.py [--quick] [--threads N] [--precision]

For the `tiny` and `small` model configs (conf/model/*.yaml) on the same token batches (toy
rallies cut into training windows, augmentation on, collated once before timing so data loading
is left out), one training step = forward, loss, backward and an AdamW step:

- scope "full": the whole decoder f (embedding, context tokens, transformer, heads, binned NLL)
  against the same model whose transformer blocks are replaced by a
  `torch.nn.TransformerEncoder` of the same size (d_model, layers, heads, feed-forward, dropout,
  pre-norm, GELU) fed the same boolean baller2vec mask; the encoder drops attention
  probabilities at our `attn_dropout` (the same computation), and a "stock" encoder row (when
  `dropout` differs from `attn_dropout`) shows `nn.TransformerEncoder` as it comes;
- scope "trunk": the transformer alone (our blocks vs the encoder) on the same embedded tokens,
  loss = mean square of the output, so that heads and embedding do not dilute the difference.

frames/s counts the valid (non-padding) frames of a batch, tokens/s those frames' object
tokens (3 a frame) plus the 4 context tokens of each window, as the training module does. The
encoder gets its mask built once (in its favour); the decoder builds its own every step, as in
training. Each variant is timed `repeats` times, alternating, and the fastest kept (a shared
machine's noise only ever slows a run down).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import torch
from omegaconf import OmegaConf
from torch import nn
from torch.utils.data import DataLoader

from sportsngen.data.tokens import Vocab, rally_arrays
from sportsngen.data.toy import make_toy_rallies
from sportsngen.model.config import ModelConfig
from sportsngen.model.decoder import SportsNGEN, baller2vec_mask
from sportsngen.model.inputs import object_features
from sportsngen.train.run import build_model_config
from sportsngen.train.windows import Augment, WindowDataset

ROOT = Path(__file__).resolve().parents[1]
BATCH_SIZE = {"tiny": 8, "small": 16}  # experiment=tiny and train.yaml's windows.batch_size


def model_config(name: str, vocab: Vocab) -> ModelConfig:
    """The ModelConfig of conf/model/<name>.yaml at 25 Hz with `vocab`."""
    node = OmegaConf.to_container(OmegaConf.load(ROOT / "conf" / "model" / f"{name}.yaml"))
    return build_model_config(node, 25.0, vocab)


def token_batches(data, vocab: Vocab, cfg: ModelConfig, batch_size: int, n_batches: int,
                  seed: int = 0) -> list[dict]:
    """`n_batches` collated training windows (random crops, flip, ball noise) of `data`."""
    arrays = rally_arrays(data, vocab)
    ds = WindowDataset(arrays, cfg.window_frames, Augment(), seed=seed)
    gen = torch.Generator().manual_seed(seed)
    loader = DataLoader(ds, batch_size=batch_size, shuffle=True, generator=gen, drop_last=True)
    out = []
    while len(out) < n_batches:
        out.extend(loader)
    return out[:n_batches]


def encoder_like(cfg: ModelConfig, stock: bool = False) -> nn.TransformerEncoder:
    """A plain TransformerEncoder with our blocks' sizes (pre-norm, GELU) and, unless `stock`,
    our attention dropout (`attn_dropout`; stock applies `dropout` to the attention too)."""
    layer = nn.TransformerEncoderLayer(cfg.d_model, cfg.n_heads, cfg.ff_mult * cfg.d_model,
                                       cfg.dropout, activation="gelu", batch_first=True,
                                       norm_first=True)
    enc = nn.TransformerEncoder(layer, cfg.n_layers, enable_nested_tensor=False)
    if not stock:
        for lyr in enc.layers:
            lyr.self_attn.dropout = cfg.attn_dropout
    return enc


def _tokens(model: SportsNGEN, batch: dict) -> torch.Tensor:
    """(B, 4 + 3T, d): context tokens then frame-major object tokens, as the decoder sees them."""
    feats = object_features(batch["pos_m"], batch["vel_mps"], batch["t_s"])
    ctx = model.context_tokens(batch["surface"], batch["tournament"], batch["serve"],
                               batch["score"])
    b, t, k, _ = feats.shape
    return torch.cat([ctx, model.embed(feats, batch["ident"]).reshape(b, t * k, -1)], dim=1)


def full_loss(model: SportsNGEN, batch: dict, encoder: nn.TransformerEncoder | None = None,
              block_mask: torch.Tensor | None = None) -> torch.Tensor:
    """The training loss (mean NLL per object token) with our blocks or with `encoder`."""
    if encoder is None:
        feats = object_features(batch["pos_m"], batch["vel_mps"], batch["t_s"])
        ctx = model.context_tokens(batch["surface"], batch["tournament"], batch["serve"],
                                   batch["score"])
        h = model(feats, batch["ident"], ctx)
    else:
        x = encoder(_tokens(model, batch), mask=block_mask)
        b, t = batch["pos_m"].shape[:2]
        h = model.ln_f(x[:, -3 * t:]).reshape(b, t, 3, -1)
    p_idx, b_idx = model.target_bins(batch["pos_m"], batch["vel_mps"], batch["next_pos_m"])
    p_nll, b_nll = model.nll(h, p_idx, b_idx)
    m = batch["has_next"].float()
    return ((p_nll.sum(-1) * m).sum() + (b_nll * m).sum()) / (3 * m.sum().clamp_min(1.0))


def _time_steps(step, batches: list, n_warmup: int) -> float:
    """Seconds per step over `batches` after `n_warmup` untimed steps."""
    for b in batches[:n_warmup]:
        step(b)
    t0 = time.perf_counter()
    for b in batches[n_warmup:]:
        step(b)
    return (time.perf_counter() - t0) / max(1, len(batches) - n_warmup)


def _variants(cfg: ModelConfig, batches: list[dict]) -> dict:
    """name -> (training step function, parameter count) for the measured variants."""
    torch.manual_seed(0)
    model = SportsNGEN(cfg).train()
    encoder = encoder_like(cfg).train()
    stock = encoder_like(cfg, stock=True).train()
    t = batches[0]["pos_m"].shape[1]
    # TransformerEncoder's boolean mask means "may NOT attend": the complement of ours.
    block_mask = ~baller2vec_mask(4, t)
    others = [p for n, p in model.named_parameters() if not n.startswith("blocks.")]
    opts = {
        "decoder": torch.optim.AdamW(model.parameters(), lr=1e-4),
        "encoder": torch.optim.AdamW(others + list(encoder.parameters()), lr=1e-4),
        "stock": torch.optim.AdamW(others + list(stock.parameters()), lr=1e-4),
        "trunk_decoder": torch.optim.AdamW(model.blocks.parameters(), lr=1e-4),
        "trunk_encoder": torch.optim.AdamW(encoder.parameters(), lr=1e-4),
    }
    with torch.no_grad():
        tokens = {id(b): _tokens(model, b).detach() for b in batches}

    def trunk_ours(x: torch.Tensor) -> torch.Tensor:
        mask = baller2vec_mask(4, t, device=x.device)
        for blk in model.blocks:
            x, _ = blk(x, mask)
        return x

    def make(kind: str):
        opt = opts[kind]

        def step(batch: dict) -> None:
            opt.zero_grad(set_to_none=True)
            if kind == "decoder":
                loss = full_loss(model, batch)
            elif kind == "encoder":
                loss = full_loss(model, batch, encoder, block_mask)
            elif kind == "stock":
                loss = full_loss(model, batch, stock, block_mask)
            elif kind == "trunk_decoder":
                loss = trunk_ours(tokens[id(batch)]).square().mean()
            else:
                loss = encoder(tokens[id(batch)], mask=block_mask).square().mean()
            loss.backward()
            opt.step()
        return step

    n_blocks = sum(p.numel() for p in model.blocks.parameters())
    n_enc = sum(p.numel() for p in encoder.parameters())
    n_model = sum(p.numel() for p in model.parameters())
    out = {"decoder": (make("decoder"), n_model),
           "encoder": (make("encoder"), n_model - n_blocks + n_enc),
           "trunk_decoder": (make("trunk_decoder"), n_blocks),
           "trunk_encoder": (make("trunk_encoder"), n_enc)}
    if cfg.dropout != cfg.attn_dropout:  # else the stock encoder is the matched one
        out["stock"] = (make("stock"), n_model - n_blocks + n_enc)
    return out


def bench_training(quick: bool, threads: int = 1,
                   configs: tuple[str, ...] = ("tiny", "small")) -> tuple[list[str], list[dict]]:
    """Training throughput, decoder vs TransformerEncoder: markdown lines and raw rows."""
    old_threads = torch.get_num_threads()
    torch.set_num_threads(threads)
    rows = []
    try:
        for name in configs:
            n_steps = (6 if quick else 20) if name == "tiny" else (3 if quick else 8)
            n_warmup, repeats = 2, 2 if quick else 3
            data = make_toy_rallies(max(40, BATCH_SIZE[name] * (n_steps + n_warmup)), seed=0)
            vocab = Vocab.from_data(data)
            cfg = model_config(name, vocab)
            batches = token_batches(data, vocab, cfg, BATCH_SIZE[name], n_steps + n_warmup)
            variants = _variants(cfg, batches)
            best = {k: float("inf") for k in variants}
            for _ in range(repeats):
                for kind, (step, _) in variants.items():
                    best[kind] = min(best[kind], _time_steps(step, batches, n_warmup))
            timed = batches[n_warmup:]
            frames = sum(int(b["valid"].sum()) for b in timed) / len(timed)
            tokens = frames * 3 + 4 * BATCH_SIZE[name]
            for kind, (_, n_params) in variants.items():
                scope = "trunk" if kind.startswith("trunk") else "full"
                model = {"stock": "encoder, stock dropout"}.get(kind, kind.removeprefix("trunk_"))
                ratio = best["trunk_encoder" if scope == "trunk" else "encoder"] / best[kind]
                rows.append({
                    "config": name, "scope": scope, "model": model, "params": n_params,
                    "batch_size": BATCH_SIZE[name], "window_frames": cfg.window_frames,
                    "seq_tokens": 4 + 3 * cfg.window_frames, "step_ms": best[kind] * 1e3,
                    "frames_per_s": frames / best[kind], "tokens_per_s": tokens / best[kind],
                    "speed_vs_encoder": ratio, "threads": threads, "steps": n_steps,
                })
                r = rows[-1]
                print(f"{name:5s} {scope:5s} {model:22s}: {r['step_ms']:8.1f} ms/step, "
                      f"{r['frames_per_s']:8.0f} frames/s, {r['tokens_per_s']:9.0f} tokens/s, "
                      f"x{ratio:.2f} the encoder's speed")
    finally:
        torch.set_num_threads(old_threads)
    lines = [
        "## Model training throughput (decoder f vs torch.nn.TransformerEncoder)",
        "",
        f"`bench_training(quick={quick})` in `bench/bench_model.py`: {threads} torch thread(s); "
        "one step = forward, loss, backward, AdamW on the same toy training batches "
        "(pre-collated). `full`: the whole model, with our blocks or a "
        "`torch.nn.TransformerEncoder` of the same size and the same boolean mask in their "
        "place; `trunk`: the transformer alone on the same embedded tokens. Best of "
        f"{2 if quick else 3} alternating runs. The encoder gets our attention dropout "
        "(`model.attn_dropout`, 0 in tiny and small; feed-forward and residual dropout "
        "`model.dropout`); \"stock dropout\" is `nn.TransformerEncoder` as it comes, dropping "
        "attention probabilities too, which rules out the fused CPU attention kernel. Speed vs "
        "encoder: the matched encoder's step time over this row's (> 1: faster).",
        "",
        "| config | scope | model | params | batch x tokens | ms/step | frames/s | tokens/s | "
        "speed vs encoder |",
        "|---|---|---|---:|---|---:|---:|---:|---:|",
    ]
    for r in rows:
        lines.append(f"| {r['config']} | {r['scope']} | {r['model']} | {r['params']:,} | "
                     f"{r['batch_size']} x {r['seq_tokens']} | {r['step_ms']:.1f} | "
                     f"{r['frames_per_s']:.0f} | {r['tokens_per_s']:.0f} | "
                     f"{r['speed_vs_encoder']:.2f} |")
    return lines, rows


def cpu_flags() -> set[str]:
    """The CPU's feature flags (Linux), empty where unknown."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("flags"):
                return set(line.split(":", 1)[1].split())
    except OSError:
        pass
    return set()


def bench_precision(quick: bool, threads: int = 2,
                    name: str = "small") -> tuple[list[str], list[dict]]:
    """A training step of the decoder in fp32 against bf16 autocast (`torch.autocast("cpu")`):
    time per step (best of alternating runs) and how far the bf16 loss lies from the fp32 loss
    on the same batches and weights."""
    old_threads = torch.get_num_threads()
    torch.set_num_threads(threads)
    n_steps, n_warmup, repeats = (3 if quick else 8), 2, (2 if quick else 3)
    try:
        data = make_toy_rallies(max(40, BATCH_SIZE[name] * (n_steps + n_warmup)), seed=0)
        vocab = Vocab.from_data(data)
        cfg = model_config(name, vocab)
        batches = token_batches(data, vocab, cfg, BATCH_SIZE[name], n_steps + n_warmup)
        torch.manual_seed(0)
        model = SportsNGEN(cfg).train()
        opt = torch.optim.AdamW(model.parameters(), lr=1e-4)

        def make(bf16: bool):
            def step(batch: dict) -> None:
                opt.zero_grad(set_to_none=True)
                with torch.autocast("cpu", dtype=torch.bfloat16, enabled=bf16):
                    loss = full_loss(model, batch)
                loss.backward()
                opt.step()
            return step

        best = {False: float("inf"), True: float("inf")}
        for _ in range(repeats):
            for bf16 in (False, True):
                best[bf16] = min(best[bf16], _time_steps(make(bf16), batches, n_warmup))
        model.eval()
        with torch.no_grad():
            diffs = []
            for b in batches:
                ref = float(full_loss(model, b))
                with torch.autocast("cpu", dtype=torch.bfloat16):
                    diffs.append(abs(float(full_loss(model, b)) - ref) / ref)
    finally:
        torch.set_num_threads(old_threads)
    flags = cpu_flags()
    native = sorted(f for f in flags if "bf16" in f or f.startswith("amx"))
    row = {"config": name, "threads": threads, "fp32_ms": best[False] * 1e3,
           "bf16_ms": best[True] * 1e3, "speedup": best[False] / best[True],
           "loss_rel_diff_max": max(diffs), "native_bf16": ", ".join(native) or "none"}
    print(f"precision {name}: fp32 {row['fp32_ms']:.0f} ms/step, bf16 autocast "
          f"{row['bf16_ms']:.0f} ms/step (x{row['speedup']:.2f}); loss differs by at most "
          f"{100 * row['loss_rel_diff_max']:.2f} %; CPU bf16 flags: {row['native_bf16']}")
    lines = [
        "## Training precision (fp32 against bf16 autocast)",
        "",
        f"`bench_precision(quick={quick})` in `bench/bench_model.py`: the `{name}` decoder's "
        f"training step (forward, loss, backward, AdamW) at {threads} torch threads, in fp32 "
        "and under `torch.autocast(\"cpu\", dtype=torch.bfloat16)`, best of "
        f"{repeats} alternating runs; the loss of the same weights on the same batches in "
        "both precisions. The CPU's native bf16 instructions (avx512_bf16, amx) decide "
        "whether bf16 can pay: without them bf16 matmuls are emulated.",
        "",
        "| config | threads | fp32 ms/step | bf16 ms/step | bf16 speed-up | largest loss "
        "difference | CPU bf16 flags |",
        "|---|---:|---:|---:|---:|---:|---|",
        f"| {name} | {threads} | {row['fp32_ms']:.0f} | {row['bf16_ms']:.0f} | "
        f"{row['speedup']:.2f} | {100 * row['loss_rel_diff_max']:.2f} % | "
        f"{row['native_bf16']} |",
        "",
        ("bf16 autocast pays here: twice the steps in the same hour if the held-out likelihood "
         "holds." if row["speedup"] > 1.2 else
         f"bf16 autocast is {1 / row['speedup']:.1f}x slower here: training stays in fp32 on "
         "this machine (a GPU or a CPU with native bf16 may differ; measure there)."),
    ]
    att = bench_attention_precision(quick, threads)
    lines += ["", *att[0]]
    return lines, [row, *att[1]]


def bench_attention_precision(quick: bool, threads: int = 2, n_rallies: int = 256,
                              repeats: int | None = None) -> tuple[list[str], list[dict]]:
    """One layer's cached attention step (`Attention.step`: the projections, the ring write
    and the two batched products over every key) of `n_rallies` rallies at a full window of
    the bundled model's shape, in fp32 and with the layer and its key/value rings in bf16:
    ms a step (best of alternating runs), the key/value bytes read a second, and the largest
    difference of the bf16 outputs relative to the largest fp32 output (issue 19, item 3)."""
    from sportsngen.model.decoder import Attention

    d, heads, window = 128, 4, 150
    slots, dh = 4 + 3 * window, d // heads
    repeats = repeats or (3 if quick else 5)
    old_threads = torch.get_num_threads()
    torch.set_num_threads(threads)
    try:
        g = torch.Generator().manual_seed(0)
        layer = Attention(d, heads, 0.0).eval()
        k = torch.randn(n_rallies, heads, slots, dh, generator=g)
        v = torch.randn(n_rallies, heads, slots, dh, generator=g)
        x = torch.randn(n_rallies, 3, d, generator=g)
        cases = {"fp32": (layer, k, v, x)}
        low = Attention(d, heads, 0.0).eval()
        low.load_state_dict(layer.state_dict())
        cases["bf16"] = (low.to(torch.bfloat16), k.bfloat16(), v.bfloat16(), x.bfloat16())
        best = dict.fromkeys(cases, float("inf"))
        out = {}
        with torch.inference_mode():
            for _ in range(repeats):
                for name, (m, kk, vv, xx) in cases.items():
                    out[name] = m.step(xx, kk, vv, slots - 3, slots)     # warm, and kept
                    t0 = time.perf_counter()
                    for _ in range(5):
                        m.step(xx, kk, vv, slots - 3, slots)
                    best[name] = min(best[name], (time.perf_counter() - t0) / 5)
        rel = float((out["bf16"].float() - out["fp32"]).abs().max() / out["fp32"].abs().max())
    finally:
        torch.set_num_threads(old_threads)
    rows = [{"precision": name, "rallies": n_rallies, "threads": threads, "ms": t * 1e3,
             "kv_gbps": 2 * k.numel() * (4 if name == "fp32" else 2) / t / 1e9}
            for name, t in best.items()]
    rows[1]["rel_diff"] = rel
    for r in rows:
        print(f"attention step {r['precision']}, {n_rallies} rallies, full window: "
              f"{r['ms']:.2f} ms, key/value reads {r['kv_gbps']:.1f} GB/s")
    lines = [
        "### Inference: one layer's cached attention step, fp32 against bf16",
        "",
        f"`bench_attention_precision` in `bench/bench_model.py`: `Attention.step` of "
        f"{n_rallies} rallies at a full window ({slots} keys, the bundled model's d = {d}, "
        f"{heads} heads) at {threads} threads, the layer and its key/value rings in fp32 and in "
        f"bf16, best of {repeats} alternating runs of 5 steps. A rollout's step runs it in each "
        "of the 4 layers.",
        "",
        "| precision | ms a step | key/value reads GB/s | largest output difference |",
        "|---|---:|---:|---:|",
        *[f"| {r['precision']} | {r['ms']:.2f} | {r['kv_gbps']:.1f} | "
          + (f"{100 * r['rel_diff']:.2f} % of the largest output |" if "rel_diff" in r
             else "- |") for r in rows],
        "",
        f"bf16 is {best['fp32'] / best['bf16']:.2f}x the speed of fp32 here, its outputs off "
        f"by up to {100 * rel:.2f} % of the largest, {rel / 2 ** -24:,.0f} times float32's "
        "relative rounding: the rollouts keep fp32 keys and values until rollouts in bf16 "
        "are shown equal in distribution to fp32's (measured, not adopted).",
    ]
    return lines, rows


if __name__ == "__main__":
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true")
    p.add_argument("--threads", type=int, default=1)
    p.add_argument("--configs", nargs="+", default=["tiny", "small"])
    p.add_argument("--precision", action="store_true", help="fp32 against bf16 autocast only")
    a = p.parse_args()
    md, _ = (bench_precision(a.quick, a.threads) if a.precision else
             bench_training(a.quick, a.threads, tuple(a.configs)))
    print("\n".join(md))
