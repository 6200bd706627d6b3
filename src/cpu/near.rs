//! The CPU twin of the trace's near cells (`src/ao/hao_trace.wgsl`: `hides_origin`, `own_cell`,
//! `near_voxel_hit`): a ray's first cells where its march would start inside an occluder.
//!
//! The march starts each ray `start_offset` cells off the surface and as many along its way, so that the
//! surface does not occlude itself through its own voxels; the depth contacts ([`super::contacts`]) trace
//! those first cells in the depth prepass. Under an overhang closer than a cell (the floor under a resting
//! sphere) the march's start lies inside the occluder: with a surface-filled sphere the ray crosses its empty
//! inside and hits the far side a metre on. And near the silhouette, where the view grazes the sphere, a
//! point a hair inside it lies many cells behind its surface along the view, so the depth contacts took it
//! for a point behind a surface in front of it. The floor right under the sphere's silhouette came out
//! lighter than a hand's breadth further out: a light band between the sphere and its shadow.
//!
//! So where the view hides the march's start (it lies behind the surface the view shows there:
//! [`hides_origin`]), two things change for each ray, and nowhere else:
//! * the depth contacts measure their thickness along the normal of the surface the view shows rather than
//!   along the view ([`super::contacts::CONTACT_GRAZING_COS`]), a point deeper than that thickness along
//!   the view counting only where its voxel is occupied (behind a bar seen edge on it is not);
//! * a ray the contacts do not stop is marched through its first cells from the surface point itself, in
//!   the finest occupancy, past the cells the surface's tangent plane crosses ([`own_cell`]: its own, as far
//!   as a point and a normal can tell); the first other occupied cell stops it ([`near_voxel_hit`]).
//!
//! In the open the view shows the march's start; beside a wall the view shows the wall, which the depth
//! contacts find as before.

use super::contacts::{NEAR_FREE_SPACE_PIXELS, ViewDepth};
use super::march::{MIN_OCCLUDING_CHORD, TraceLevel, ray_box, safe_inverse};
use glam::Vec3;

/// How far past the cells the surface's tangent plane crosses a cell still counts as the surface's own, in
/// cells (WGSL: `OWN_CELL_MARGIN`): the prepass's normal and the mesh's facets part by a few degrees.
pub const OWN_CELL_MARGIN: f32 = 0.125;
/// Cells the near march visits at most (WGSL: `NEAR_VOXEL_STEPS`): a ray crosses at most seven cells in two
/// cells' length, and one more finishes a run.
pub const NEAR_VOXEL_STEPS: u32 = 8;

/// Whether the view hides the point `origin` (where a ray's march starts): behind the surface the view
/// shows at its pixel by more than
/// [`CONTACT_DEPTH_EPSILON`](super::contacts::CONTACT_DEPTH_EPSILON) of its depth, however far (WGSL:
/// `hides_origin`).
pub fn hides_origin(view: &ViewDepth, origin: Vec3, depth_loads: &mut u64) -> bool {
    view.behind(origin, f32::INFINITY, false, depth_loads)
}

/// Whether cell `cell` (a level's cells) is the surface's own: the plane through `surface` (the same
/// cells) with normal `normal` crosses it, or passes within [`OWN_CELL_MARGIN`] of it (WGSL: `own_cell`).
pub fn own_cell(cell: Vec3, surface: Vec3, normal: Vec3) -> bool {
    let extent = 0.5 * (normal.x.abs() + normal.y.abs() + normal.z.abs()) + OWN_CELL_MARGIN;
    normal.dot(cell + Vec3::splat(0.5) - surface).abs() <= extent
}

/// What a near march found: the world distance from the surface point to its hit, as the falloff takes it
/// (half a cell past the entry, as the march's), and the cells it visited.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NearVoxelHit {
    /// World distance to the occluder, or `None`.
    pub distance: Option<f32>,
    /// Occupancy texels loaded.
    pub visits: u32,
}

/// The first occupied cell of `level`'s finest occupancy that is not the surface's own ([`own_cell`]) along
/// ray `dir` from the surface point `world` (normal `normal`) within `reach` cells, entered by a run of such
/// cells that the ray goes [`MIN_OCCLUDING_CHORD`] through (WGSL: `near_voxel_hit`). With `view`, a hit
/// whose surface (half a cell past its entry) the view shows in free space by a pixel is passed, as the
/// march's near hits are.
pub fn near_voxel_hit(
    level: &TraceLevel,
    view: Option<&ViewDepth>,
    world: Vec3,
    normal: Vec3,
    dir: Vec3,
    reach: f32,
    depth_loads: &mut u64,
) -> NearVoxelHit {
    let o = level.level_position(world);
    let inv = safe_inverse(dir);
    let mut t = 0.0f32;
    let mut run_start = 0.0f32;
    let mut run_length = 0.0f32;
    let mut visits = 0;
    while visits < NEAR_VOXEL_STEPS && t < reach {
        visits += 1;
        let cell = (o + dir * t).floor();
        let exit = ray_box(o, inv, cell, cell + Vec3::ONE).y;
        let other = level.mips.occupied(cell.as_ivec3()) && !own_cell(cell, o, normal);
        if other {
            if run_length == 0.0 {
                run_start = t;
            }
            run_length += exit - t;
        } else {
            run_length = 0.0;
        }
        if run_length >= MIN_OCCLUDING_CHORD {
            let distance = (run_start + 0.5) * level.cell_size;
            let surface = world + dir * distance;
            let free = view.is_some_and(|v| {
                let margin = NEAR_FREE_SPACE_PIXELS * v.pixel_size((v.clip_from_world * surface.extend(1.0)).w);
                v.shows_free_space(surface, margin, depth_loads)
            });
            if !free {
                return NearVoxelHit { distance: Some(distance), visits };
            }
            run_length = 0.0;
        }
        t = exit.max(t) + 1.0e-3;
    }
    NearVoxelHit { distance: None, visits }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cpu::grid::{VoxelGrid, VoxelOccupancy};
    use crate::cpu::march::VoxelMips;
    use glam::{IVec3, UVec3};

    #[test]
    fn the_cells_its_tangent_plane_crosses_are_the_surfaces_own() {
        // A floor at height 1.3 (cells): its layer is 1; the layers above and below are not its own.
        let (p, up) = (Vec3::new(4.5, 1.3, 4.5), Vec3::Y);
        assert!(own_cell(Vec3::new(6.0, 1.0, 2.0), p, up));
        assert!(!own_cell(Vec3::new(4.0, 2.0, 4.0), p, up));
        assert!(!own_cell(Vec3::new(4.0, 0.0, 4.0), p, up));
        // A wall at 45 degrees crosses the cells along its diagonal, and those beside them by a corner.
        let n = Vec3::new(1.0, 1.0, 0.0).normalize();
        let p = Vec3::new(4.5, 4.5, 4.5);
        assert!(own_cell(Vec3::new(5.0, 3.0, 0.0), p, n));
        assert!(own_cell(Vec3::new(5.0, 4.0, 7.0), p, n));
        assert!(!own_cell(Vec3::new(5.0, 5.0, 4.0), p, n));
    }

    /// A floor (its layer at y = 1, the surface at 1.3 cells) under an overhang whose underside lies in
    /// layer 2: a quarter of a cell over the floor's layer, as a resting sphere's a hand's breadth from its
    /// contact. A ray up from the floor stops at the overhang's layer, half a cell past its entry; one along
    /// the floor passes the floor's own cells and finds nothing within two cells; one toward the overhang's
    /// edge (it ends over x = 5) finds it only where it still covers.
    #[test]
    fn a_ray_from_under_an_overhang_stops_at_it_past_the_floors_own_cells() {
        let grid = VoxelGrid::new(Vec3::ZERO, 0.5, UVec3::splat(16)).unwrap();
        let occupancy = VoxelOccupancy::new(grid, false);
        for i in 0..16 {
            for k in 0..16 {
                occupancy.set(UVec3::new(i, 1, k));
                if i <= 5 {
                    occupancy.set(UVec3::new(i, 2, k));
                }
            }
        }
        let mips = VoxelMips::new(&occupancy, 4);
        let level = TraceLevel { origin: Vec3::ZERO, cell_size: 0.5, window_min: IVec3::ZERO, mips: &mips };
        let world = Vec3::new(3.5, 1.3, 4.5) * 0.5;
        let mut loads = 0;
        let hit = |dir: Vec3| near_voxel_hit(&level, None, world, Vec3::Y, dir.normalize(), 2.0, &mut 0);
        let up = hit(Vec3::Y);
        // The layer's entry 0.7 cells up (and the step past the floor's exit, 1e-3).
        assert!(up.distance.is_some_and(|d| (d - (0.7 + 0.5) * 0.5).abs() < 1.0e-3), "{up:?}");
        let along = hit(Vec3::new(1.0, 0.05, 0.0));
        assert_eq!(along.distance, None, "{along:?}");
        assert!(along.visits <= NEAR_VOXEL_STEPS);
        // Toward the edge at 45 degrees: it enters layer 2 at x = 4.2, under the overhang.
        assert!(hit(Vec3::new(1.0, 1.0, 0.0)).distance.is_some());
        // Away from the overhang's edge, from x = 6.5: it enters layer 2 at x = 7.2, past the edge.
        let beyond = near_voxel_hit(
            &level,
            None,
            Vec3::new(6.5, 1.3, 4.5) * 0.5,
            Vec3::Y,
            Vec3::new(1.0, 1.0, 0.0).normalize(),
            2.0,
            &mut loads,
        );
        assert_eq!(beyond.distance, None, "{beyond:?}");
        // No view given, no depth read.
        assert_eq!(loads, 0);
    }
}
