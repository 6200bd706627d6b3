// The lighting volume (src/gi/lighting.rs): each occupied voxel's outgoing diffuse radiance under Bevy's
// lights, each shadowed by a march through the voxels toward it, from the multi-valued voxels' average
// albedo and normal; written as rgb9e5 into an R32Uint texture laid out as the voxel texture's mip 0. Every
// frame one of `phases` slabs of 4-cell rows of each level, in turn. CPU twin: `bevy_hao::cpu::lighting`
// (`voxel_radiance`, `light_reaches`).
#import bevy_hao::voxel_grid::{voxel_grid, voxel_occupied, voxel_texel, voxel_albedo_at, voxel_normal_at, march_cascades}
#import bevy_hao::gi_common::{GiLight, light_incident, pack_rgb9e5}

// src/gi/lighting.rs: `GpuGiLightingParams`.
struct GiLightingParams {
    light_count: u32,
    // This frame's slab, of `phases`.
    phase: u32,
    phases: u32,
    // Rows of 4 cells along z of a level's window.
    blocks_z: u32,
}

@group(0) @binding(0) var<uniform> params: GiLightingParams;
@group(0) @binding(1) var<storage, read> lights: array<GiLight>;
@group(0) @binding(2) var radiance_out: texture_storage_3d<r32uint, write>;
// The voxel levels are bound at group 2 (`bevy_hao::voxel_grid`).

// cpu/lighting.rs: SHADOW_START_CELLS, SHADOW_STEPS, SHADOW_NORMAL_MIN
const SHADOW_START_CELLS: f32 = 1.0;
const SHADOW_STEPS: u32 = 64u;
const SHADOW_NORMAL_MIN: f32 = 0.25;

const PI: f32 = 3.141592653589793;

// cpu/lighting.rs: cell_center. The centre of cell `cell` of a level's window, in world space.
fn cell_center(level: u32, cell: vec3<i32>) -> vec3<f32> {
    let l = voxel_grid.levels[level];
    return l.origin + (vec3<f32>(cell + l.window_min) + vec3<f32>(0.5)) * l.cell_size;
}

// cpu/lighting.rs: light_reaches. Whether the light from `to_light`, `distance` away, reaches the voxel at
// `center` of level `level` with average normal `normal`: a march from a cell off the centre along the normal
// and a cell along the ray that no run of occupied cells stops (out of visits counts as lit).
fn light_reaches(level: u32, center: vec3<f32>, normal: vec3<f32>, to_light: vec3<f32>, distance: f32) -> bool {
    let cell = voxel_grid.levels[level].cell_size;
    let lift = select(vec3<f32>(0.0), normalize(normal), length(normal) >= SHADOW_NORMAL_MIN);
    let origin = center + lift * (SHADOW_START_CELLS * cell);
    let d = min(distance, 1.0e30) - dot(lift, to_light) * SHADOW_START_CELLS * cell;
    if d <= SHADOW_START_CELLS * cell {
        return true;
    }
    return march_cascades(origin, to_light, level, SHADOW_START_CELLS, d, SHADOW_STEPS).x < 0.0;
}

// cpu/lighting.rs: voxel_radiance. albedo / pi * sum(E * max(n . l, 0)) over the lights that reach the voxel,
// with the average normal as it is.
fn voxel_radiance(level: u32, cell: vec3<i32>, albedo: vec3<f32>, normal: vec3<f32>) -> vec3<f32> {
    let center = cell_center(level, cell);
    var sum = vec3<f32>(0.0);
    for (var i = 0u; i < params.light_count; i++) {
        let incident = light_incident(lights[i], center);
        let facing = dot(normal, incident.to_light);
        let strongest = max(max(incident.illuminance.x, incident.illuminance.y), incident.illuminance.z);
        if !(facing > 0.0) || !(strongest > 0.0) {
            continue;
        }
        if light_reaches(level, center, normal, incident.to_light, incident.distance) {
            sum += albedo / PI * incident.illuminance * facing;
        }
    }
    return sum;
}

@compute @workgroup_size(4, 4, 4)
fn light_voxels(@builtin(workgroup_id) group: vec3<u32>, @builtin(local_invocation_id) local: vec3<u32>) {
    let per_level = (params.blocks_z + params.phases - 1u) / params.phases;
    let level = group.z / per_level;
    let row = (group.z % per_level) * params.phases + params.phase;
    if level >= voxel_grid.level_count || row >= params.blocks_z {
        return;
    }
    let c = vec3<u32>(group.x, group.y, row) * 4u + local;
    if any(c >= voxel_grid.levels[level].dims) {
        return;
    }
    let cell = vec3<i32>(c);
    var packed = 0u;
    if voxel_occupied(level, cell, 0u) {
        let albedo = voxel_albedo_at(level, cell);
        packed = pack_rgb9e5(voxel_radiance(level, cell, albedo.rgb, voxel_normal_at(level, cell)));
    }
    textureStore(radiance_out, voxel_texel(level, cell), vec4<u32>(packed, 0u, 0u, 0u));
}
