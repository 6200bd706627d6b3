// Hybrid ambient occlusion, pass 1: per pixel (or per 2x2 pixels at half resolution), cosine-weighted rays
// from the surface (position from the depth prepass, normal from the normal prepass) through the voxel
// texture, with empty-space skipping on its max-reduced mips. Writes the noisy AO (1 = open, 0 = occluded)
// with the pixel's view depth and octahedral normal, which the denoiser weighs by.
// CPU twin: `bevy_hao::cpu::ao::voxel_ambient_occlusion`. The voxel levels are bound at group 2.
#import bevy_render::view::View
#import bevy_hao::hao_common::{
    HaoSettings, ray_rotation, hemisphere_direction, orthonormal_basis, ao_falloff,
    octahedral_encode,
}
#import bevy_hao::voxel_grid::{voxel_grid, ray_start_level, march_cascades}

@group(0) @binding(0) var depth_texture: texture_depth_2d;
@group(0) @binding(1) var normal_texture: texture_2d<f32>;
@group(0) @binding(2) var<uniform> settings: HaoSettings;
@group(0) @binding(3) var ao_out: texture_storage_2d<rgba16float, write>;
@group(1) @binding(0) var<uniform> view: View;

fn world_position(pixel: vec2<u32>, depth: f32) -> vec3<f32> {
    let uv = (vec2<f32>(pixel) + 0.5) / view.viewport.zw;
    let ndc = vec2<f32>(uv.x * 2.0 - 1.0, 1.0 - uv.y * 2.0);
    let p = view.world_from_clip * vec4<f32>(ndc, depth, 1.0);
    return p.xyz / p.w;
}

@compute @workgroup_size(8, 8, 1)
fn trace(@builtin(global_invocation_id) gid: vec3<u32>) {
    let out_size = textureDimensions(ao_out);
    if any(gid.xy >= out_size) {
        return;
    }
    let scale = select(1u, 2u, settings.half_resolution != 0u);
    let pixel = min(gid.xy * scale, textureDimensions(depth_texture) - vec2<u32>(1u));
    let depth = textureLoad(depth_texture, pixel, 0);
    if depth <= 0.0 {
        // Background: depth 0 tells the denoiser to skip it.
        textureStore(ao_out, gid.xy, vec4<f32>(1.0, 0.0, 0.0, 0.0));
        return;
    }
    let world = world_position(pixel, depth);
    let normal = normalize(textureLoad(normal_texture, pixel, 0).xyz * 2.0 - 1.0);
    let view_depth = -(view.view_from_world * vec4<f32>(world, 1.0)).z;
    let packed_normal = octahedral_encode(normal);
    if voxel_grid.level_count == 0u {
        textureStore(ao_out, gid.xy, vec4<f32>(1.0, view_depth, packed_normal));
        return;
    }
    let pf = vec2<f32>(pixel);
    let rotation = ray_rotation(pf, settings.frame);
    var occlusion = 0.0;
    let basis = orthonormal_basis(normal);
    for (var i = 0u; i < settings.rays; i++) {
        let dir = hemisphere_direction(basis, i, settings.rays, rotation);
        // The finest level that holds the surface (blended across its border), then coarser ones.
        let start = ray_start_level(world, i, rotation);
        let origin = world + normal * (settings.start_offset * voxel_grid.levels[start].cell_size);
        let hit = march_cascades(origin, dir, start, settings.start_offset, settings.max_distance, settings.steps);
        if hit.x >= 0.0 {
            // The surface lies somewhere in the first occupied cell, on average half a cell past its entry.
            let cell = voxel_grid.levels[u32(hit.y)].cell_size;
            let d = length(origin + dir * (hit.x + 0.5 * cell) - world);
            occlusion += ao_falloff(d, settings.max_distance, settings.falloff);
        }
    }
    let ao = clamp(1.0 - settings.intensity * occlusion / f32(settings.rays), 0.0, 1.0);
    textureStore(ao_out, gid.xy, vec4<f32>(ao, view_depth, packed_normal));
}
