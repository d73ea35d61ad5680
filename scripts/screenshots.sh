#!/usr/bin/env bash
# Regenerates screenshots/ from the project itself:
#   screenshots/panel.png                      the control panel (egui_kittest snapshot, lavapipe)
#   screenshots/rerun-kalthoff-winkler.png     the Rerun viewer on a scripted hybrid Kalthoff–Winkler
#                                              run: damage, the scheme mask (standard / WLS), Ω_s
# Needs (Debian): xvfb mesa-vulkan-drivers libvulkan1, and `rerun` (pip install 'rerun-sdk==0.36.3').
set -euo pipefail
cd "$(dirname "$0")/.."
need=()
for p in xvfb mesa-vulkan-drivers libvulkan1; do
    dpkg -s "$p" >/dev/null 2>&1 || need+=("$p")
done
if [ ${#need[@]} -gt 0 ]; then
    sudo=""; [ "$(id -u)" -ne 0 ] && sudo="sudo"
    $sudo apt-get update -qq && $sudo env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${need[@]}"
fi
command -v rerun >/dev/null || pip install -q 'rerun-sdk==0.36.3'

# The panel: rendered by the snapshot test, written to tests/snapshots/panel.png.
UPDATE_SNAPSHOTS=1 cargo test --release --test suite panel::panel_snapshot
cp tests/snapshots/panel.png screenshots/panel.png

# The viewer: a hybrid-adaptive Kalthoff–Winkler run with a command script (χ, Δt, and a
# restart with m = 3).
work=$(mktemp -d)
trap 'kill ${xvfb:-0} 2>/dev/null || true; rm -rf "$work"' EXIT
cargo run --release -- record kalthoff-winkler --variant small-hybrid -q \
    --script scripts/kalthoff-winkler-demo.script -o "$work/kw.rrd"
Xvfb :99 -screen 0 1280x800x24 -nolisten tcp >/dev/null 2>&1 &
xvfb=$!
sleep 1
mkdir -p "$work/xdg" && chmod 700 "$work/xdg"
# The recording carries its own first view (src/record/blueprint.rs). The viewer exits with
# code 102 after writing the picture: check the file, not the code.
DISPLAY=:99 XDG_RUNTIME_DIR="$work/xdg" rerun "$work/kw.rrd" --window-size 1200x760 \
    --screenshot-to screenshots/rerun-kalthoff-winkler.png >/dev/null 2>&1 || true
test -s screenshots/rerun-kalthoff-winkler.png
echo "screenshots/ updated"
