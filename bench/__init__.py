"""Benchmarks (see docs/benchmarks.md). Their editors run without the shader
warm-up process (app/warmup.py): each run has a fresh state folder, so it would
warm again every run and take the CPU the measurement needs."""
import os

os.environ.setdefault("INFINITEX_NO_WARMUP", "1")
