// Hybrid ambient occlusion, pass 2: the horizontal half of a separable bilateral filter (depth- and
// normal-aware) over the accumulated AO, at full resolution. It reads and writes the temporal history's
// layout (ao, view depth, packed normal, frames); `bilateral_line` in hao_common.wgsl is the filter, and
// `hao_denoise_vertical.wgsl` the vertical half.
#import bevy_hao::hao_common::{HaoSettings, bilateral_line}

@group(0) @binding(0) var accumulated: texture_2d<f32>;
@group(0) @binding(1) var<uniform> settings: HaoSettings;
@group(0) @binding(2) var filtered_out: texture_storage_2d<rgba32float, write>;

@compute @workgroup_size(#{SCREEN_WORKGROUP}, #{SCREEN_WORKGROUP}, 1)
fn denoise_horizontal(@builtin(global_invocation_id) gid: vec3<u32>) {
    if all(gid.xy < textureDimensions(accumulated)) {
        textureStore(filtered_out, gid.xy, bilateral_line(accumulated, gid.xy, vec2<i32>(1, 0), settings.denoise_radius));
    }
}
