//! Solid voxelization (Dong et al. 2004): the inside of a closed mesh filled by parity along z. Every
//! triangle crosses the vertical lines through the cell centres its projection onto xy covers; a cell is
//! inside when an odd number of crossings lie below its centre in its column. The surface voxelization
//! (any mode) plus the inside is the solid.
//!
//! A crossing is counted once where a line meets two triangles at their shared edge or vertex: the
//! projected triangles own their edges by the top-left rule, and an edge's function is computed the same
//! way from both of its triangles ([`edge_function`]), so in `f32` too the two agree exactly.
//! Triangles seen edge-on from above (zero projected area) cross no line.
//!
//! A mesh that is not closed ([`open_edge_count`]) leaves some columns with an odd number of crossings:
//! those columns are not filled at all (counted in [`SolidFill::odd_columns`]), so an open mesh is filled
//! where its columns pair up and hollow elsewhere. Two closed meshes that overlap fill their overlap only
//! if they are filled separately: in one call the crossings of both pair up, and the shared part is
//! left out.
//!
//! The GPU voxelizer does the same for occluders with `VoxelFill::Solid` (voxelize_solid.wgsl); this is its
//! CPU twin.

use super::grid::VoxelOccupancy;
use super::mesh::TriangleMesh;
use super::voxelize::{InjectionRegion, grid_space_position, storage_index};
use glam::{Affine3A, IVec3, Vec2, Vec3};
use std::collections::HashMap;

/// What [`fill_solid`] did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SolidFill {
    /// Cells set inside that were not set before.
    pub filled: u64,
    /// Columns crossed an odd number of times (the mesh is not closed there), left unfilled.
    pub odd_columns: u64,
    /// Crossings found.
    pub crossings: u64,
}

/// Edges that keep the mesh from being closed: directed edges (by corner position, so that duplicated
/// vertices count as one) that are not used exactly once with their reverse used exactly once.
pub fn open_edge_count(mesh: &TriangleMesh) -> u64 {
    let key = |p: Vec3| p.to_array().map(f32::to_bits);
    let mut edges: HashMap<([u32; 3], [u32; 3]), u32> = HashMap::new();
    for t in 0..mesh.triangle_count() {
        let Some(v) = mesh.triangle(t) else { continue };
        for k in 0..3 {
            let (a, b) = (key(v[k]), key(v[(k + 1) % 3]));
            if a != b {
                *edges.entry((a, b)).or_insert(0) += 1;
            }
        }
    }
    edges.iter().filter(|&(&(a, b), &n)| n != 1 || edges.get(&(b, a)) != Some(&1)).count() as u64
}

/// Twice the signed area of `a b c` projected onto xy, computed the same way whichever way round the edge
/// `a b` is given (from its lexicographically smaller end, negated if need be), so that two triangles
/// sharing an edge get exactly opposite values for a point. WGSL: `edge_function`.
#[inline]
pub fn edge_function(a: Vec2, b: Vec2, c: Vec2) -> f32 {
    let raw = |a: Vec2, b: Vec2| (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
    if (b.x, b.y) < (a.x, a.y) { -raw(b, a) } else { raw(a, b) }
}

/// Whether a point exactly on the edge `a -> b` of a counter-clockwise triangle belongs to it (top-left
/// rule, y up: edges that go down, and horizontal edges that go left).
#[inline]
fn owns_edge(a: Vec2, b: Vec2) -> bool {
    let d = b - a;
    d.y < 0.0 || (d.y == 0.0 && d.x < 0.0)
}

/// Where the vertical line through `c` (a column's centre) crosses the grid-space triangle `v`, if it
/// does (see the module docs for shared edges). WGSL: `column_crossing`.
#[inline]
pub fn column_crossing(v: [Vec3; 3], c: Vec2) -> Option<f32> {
    // Counter-clockwise in the projection.
    let [a, mut b, mut e] = v;
    if edge_function(a.truncate(), b.truncate(), e.truncate()) < 0.0 {
        std::mem::swap(&mut b, &mut e);
    }
    let (p0, p1, p2) = (a.truncate(), b.truncate(), e.truncate());
    let w = [edge_function(p1, p2, c), edge_function(p2, p0, c), edge_function(p0, p1, c)];
    let owns = [owns_edge(p1, p2), owns_edge(p2, p0), owns_edge(p0, p1)];
    let area = w[0] + w[1] + w[2];
    ((0..3).all(|k| w[k] > 0.0 || (w[k] == 0.0 && owns[k])) && area > 0.0)
        .then(|| (w[0] * a.z + w[1] * b.z + w[2] * e.z) / area)
}

/// Fills the inside of `mesh` (transformed to grid space by `grid_from_local`) into `out`, which should
/// already hold its surface. Cells are inside by their centres; see the module docs.
pub fn fill_solid(mesh: &TriangleMesh, grid_from_local: Affine3A, out: &VoxelOccupancy) -> SolidFill {
    fill_solid_in_region(mesh, grid_from_local, &InjectionRegion::whole(out.grid().dims), out)
}

/// [`fill_solid`] into the cells of `region` of `out`, stored relative to the region's window (as
/// [`super::voxelize::voxelize_mesh_in_region`] stores them): a column of the region is filled from its
/// crossings at any height (those below the region count, those above end nothing in it), and left alone
/// if it has an odd number of crossings in all. WGSL: voxelize_solid.wgsl.
pub fn fill_solid_in_region(
    mesh: &TriangleMesh,
    grid_from_local: Affine3A,
    region: &InjectionRegion,
    out: &VoxelOccupancy,
) -> SolidFill {
    let grid = *out.grid();
    let size = (region.max - region.min).max(IVec3::ZERO);
    let mut columns: Vec<Vec<f32>> = vec![Vec::new(); size.x as usize * size.y as usize];
    let mut fill = SolidFill::default();
    for t in 0..mesh.triangle_count() {
        let Some(v) = mesh.triangle(t) else { continue };
        let v = v.map(|p| grid_space_position(&grid_from_local, p));
        if !v.iter().all(|p| p.is_finite()) {
            continue;
        }
        let lo = v[0].min(v[1]).min(v[2]).truncate();
        let hi = v[0].max(v[1]).max(v[2]).truncate();
        // The region's columns whose centres (i + 0.5, j + 0.5) lie in the box.
        let first = (lo - 0.5).ceil().max(region.min.truncate().as_vec2());
        let last = (hi - 0.5).floor().min((region.max.truncate() - 1).as_vec2());
        if !(first.x <= last.x && first.y <= last.y) {
            continue;
        }
        for j in first.y as i32..=last.y as i32 {
            for i in first.x as i32..=last.x as i32 {
                if let Some(z) = column_crossing(v, Vec2::new(i as f32 + 0.5, j as f32 + 0.5)) {
                    columns[((i - region.min.x) + size.x * (j - region.min.y)) as usize].push(z);
                    fill.crossings += 1;
                }
            }
        }
    }
    for (index, crossings) in columns.iter_mut().enumerate() {
        if crossings.is_empty() {
            continue;
        }
        if crossings.len() % 2 == 1 {
            fill.odd_columns += 1;
            continue;
        }
        crossings.sort_by(f32::total_cmp);
        let i = region.min.x + index as i32 % size.x;
        let j = region.min.y + index as i32 / size.x;
        for pair in crossings.chunks_exact(2) {
            // Cells k with centre k + 0.5 in (enter, leave].
            let from = crossing_cell(pair[0]).max(region.min.z);
            let to = crossing_cell(pair[1]).saturating_sub(1).min(region.max.z - 1);
            for k in from..=to {
                let cell = grid.cell_of_index(storage_index(IVec3::new(i, j, k), region, grid.dims));
                if !out.is_set(cell) {
                    out.set(cell);
                    fill.filled += 1;
                }
            }
        }
    }
    fill
}

/// The first cell whose centre lies above a crossing at `z`: `floor(z - 0.5) + 1`, saturating at the ends
/// of `i32`. WGSL: `crossing_cell` (which clamps to the region first).
#[inline]
pub fn crossing_cell(z: f32) -> i32 {
    ((z - 0.5).floor() + 1.0) as i32
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cpu::VoxelGrid;
    use glam::UVec3;

    /// A closed box from `lo` to `hi` (12 triangles, outward).
    fn cuboid(lo: Vec3, hi: Vec3) -> TriangleMesh {
        let c = |x: bool, y: bool, z: bool| {
            Vec3::new(if x { hi.x } else { lo.x }, if y { hi.y } else { lo.y }, if z { hi.z } else { lo.z })
        };
        let positions: Vec<Vec3> = (0..8).map(|k| c(k & 1 != 0, k & 2 != 0, k & 4 != 0)).collect();
        let quads = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]];
        let triangles = quads.iter().flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]]).collect();
        TriangleMesh::new(positions, triangles)
    }

    #[test]
    fn a_box_is_filled_by_its_cell_centres() {
        let g = VoxelGrid::new(Vec3::ZERO, 1.0, UVec3::splat(16)).unwrap();
        // Corners on cell centres' lines (x = 2.5): shared edges and vertices are met exactly.
        let mesh = cuboid(Vec3::new(2.5, 3.5, 1.2), Vec3::new(10.5, 8.5, 12.7));
        assert_eq!(open_edge_count(&mesh), 0);
        let out = VoxelOccupancy::new(g, false);
        let f = fill_solid(&mesh, Affine3A::IDENTITY, &out);
        assert_eq!(f.odd_columns, 0);
        // Columns with centres in [2.5, 10.5] x [3.5, 8.5], the left and top edges owning theirs (top-left
        // rule) and the right and bottom ones not: x 2..=9, y 4..=8; cells with centres in (1.2, 12.7]:
        // z 1..=12.
        for z in 0..16 {
            for y in 0..16 {
                for x in 0..16 {
                    let inside = (2..=9).contains(&x) && (4..=8).contains(&y) && (1..=12).contains(&z);
                    assert_eq!(out.is_set(UVec3::new(x, y, z)), inside, "{x} {y} {z}");
                }
            }
        }
        assert_eq!(f.filled, 8 * 5 * 12);
    }

    #[test]
    fn an_open_mesh_is_reported_and_its_odd_columns_left_hollow() {
        let g = VoxelGrid::new(Vec3::ZERO, 1.0, UVec3::splat(16)).unwrap();
        let mut mesh = cuboid(Vec3::splat(2.3), Vec3::splat(9.7));
        mesh.triangles.drain(2..4); // the top face removed: its 4 rim edges have no twin
        assert_eq!(open_edge_count(&mesh), 4);
        let out = VoxelOccupancy::new(g, false);
        let f = fill_solid(&mesh, Affine3A::IDENTITY, &out);
        // Every column over the box (centres 2.5..=9.5) meets only the bottom.
        assert_eq!(f.odd_columns, 8 * 8);
        assert_eq!(f.filled, 0);
    }
}
