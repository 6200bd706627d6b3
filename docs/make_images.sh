#!/usr/bin/env bash
# Renders the README's pictures headless (on Mesa's lavapipe on a machine without a GPU) from the built-in
# procedural cathedral, with the examples' own commands. Run from the repository root:
#   docs/make_images.sh
set -euo pipefail
out=docs/images
mkdir -p "$out"
size=800x450
run() { cargo run --release --example "$@"; }
run sibenik -- --headless --frames 30 --size $size --ao hao --screenshot $out/cathedral_hao.png
run sibenik -- --headless --frames 30 --size $size --ao off --screenshot $out/cathedral_no_ao.png
run sibenik -- --headless --frames 30 --size $size --ao ssao --screenshot $out/cathedral_ssao.png
run sibenik -- --headless --frames 30 --size $size --view ao --screenshot $out/cathedral_hao_only.png
run sibenik -- --headless --frames 30 --size $size --ao ssao --view ao --screenshot $out/cathedral_ssao_only.png
run sibenik -- --headless --frames 30 --size $size --view voxels --screenshot $out/cathedral_voxels.png
run sibenik -- --headless --frames 30 --size $size --view counts --screenshot $out/cathedral_point_counts.png
run sibenik -- --headless --frames 30 --size $size --view cascades --screenshot $out/cathedral_cascades.png
run sibenik -- --headless --frames 30 --size $size --view albedo --screenshot $out/cathedral_albedo.png
run sibenik -- --headless --frames 30 --size $size --view normals --screenshot $out/cathedral_normals.png
run dynamic -- --headless --frames 60 --size $size --view static-dynamic --screenshot $out/dynamic_static_dynamic.png
cargo run --release -p bevy_hao_tools --bin ao_compare -- --size 320x180 --rays 256 --out $out/ao_compare_cathedral.png
# Voxel GI on the GI room: without and with it (the example's sun through the ceiling), and the reference's
# indirect light beside the plugin's (gi_compare's first panel of each row, under the example's sun).
room=(builtin:gi-room --headless --size 480x270 --camera=2.47,0.9,0 --look=-3,0.8,0)
run sibenik -- "${room[@]}" --frames 40 --screenshot $out/gi_room_no_gi.png
run sibenik -- "${room[@]}" --gi --frames 840 --screenshot $out/gi_room_gi.png
cargo run --release -p bevy_hao_tools --bin gi_compare -- builtin:gi-room --gpu --bounces 16 --sun=-0.4,-0.55,-0.25 \
    --illuminance 25000 --camera=2.47,0.9,0 --look=-3,0.8,0 --size 480x270 --out /tmp/gi_room_compare.png
python3 -c "
from PIL import Image
r = Image.open('/tmp/gi_room_compare.png')
r.crop((0, 0, 480, 270)).save('$out/gi_room_reference.png')
r.crop((0, 274, 480, 544)).save('$out/gi_room_gpu.png')"
# The window with the inspector (needs a display; xvfb-run provides one).
if command -v xvfb-run >/dev/null; then
    cargo build --release --example sibenik
    xvfb-run -a -s "-screen 0 1280x720x24" cargo run --release --example sibenik -- --screenshot $out/inspector.png --frames 60
fi
