#!/usr/bin/env bash
# Regenerates the speed-against-error results shown in docs/validation.md (screenshots/sweeps/).
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release
bin=target/release/peridyn
out=screenshots/sweeps
schemes=standard,wls-2,wls-4,wls-6
# 1D static, m-convergence at δ = 6 (m = 6, 12, 24, 33), with and without β.
$bin sweep static-1d-manufactured --vary discretization.spacing=1,0.5,0.25,0.18181818181818182 \
    --schemes $schemes --out $out/static-1d-m
$bin sweep static-1d-manufactured --variant no-beta \
    --vary discretization.spacing=1,0.5,0.25,0.18181818181818182 --schemes standard \
    --out $out/static-1d-m-no-beta
# 1D static, δ-convergence at m = 12 (δ = 8 … 0.25), with and without β.
deltas=0.6666666666666666,0.3333333333333333,0.16666666666666666,0.08333333333333333,0.041666666666666664,0.020833333333333332
$bin sweep static-1d-manufactured --variant delta --vary discretization.spacing=$deltas \
    --schemes $schemes --out $out/static-1d-delta
$bin sweep static-1d-manufactured --variant delta --set discretization.volume_correction=false \
    --vary discretization.spacing=$deltas --schemes standard --out $out/static-1d-delta-no-beta
# 2D diffusion, δ = 4Δx and 5Δx, uniform and perturbed grids, to T = 0.1.
$bin sweep diffusion-2d-manufactured --vary 'discretization.horizon=4 dx,5 dx' \
    --schemes standard,wls-2,wls-4 --out $out/diffusion-2d-uniform
$bin sweep diffusion-2d-manufactured --variant perturbed --vary 'discretization.horizon=4 dx,5 dx' \
    --schemes standard,wls-2,wls-4 --out $out/diffusion-2d-perturbed
# 2D diffusion, resolution study at δ = 5Δx on the uniform grid (T = 0.01).
$bin sweep diffusion-2d-manufactured --set 'time.end="1000 steps"' \
    --vary discretization.spacing=0.05263157894736842,0.02564102564102564,0.012658227848101266 \
    --schemes standard,wls-2,wls-4 --out $out/diffusion-2d-resolution
