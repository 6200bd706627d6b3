//! Quality figures against the ground truth: bias, excess voxels, and the six-direction watertight test; and
//! of an AO image against its reference, the isolated specks ([`specks`]).

use bevy_hao::cpu::VoxelOccupancy;
use glam::UVec3;

/// A voxelization compared with the conservative ground truth.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Comparison {
    /// Voxels set in the result.
    pub result_voxels: u64,
    /// Voxels set in the ground truth.
    pub truth_voxels: u64,
    /// Ground-truth voxels missing from the result.
    pub missing: u64,
    /// Result voxels absent from the ground truth (a voxel set that no triangle overlaps).
    pub excess: u64,
}

impl Comparison {
    /// The paper's bias (Figure 10): missing voxels / ground-truth voxels (0 for an empty ground truth).
    pub fn bias(&self) -> f64 {
        if self.truth_voxels == 0 { 0.0 } else { self.missing as f64 / self.truth_voxels as f64 }
    }
}

/// Missing voxels split by how the surface meets them ([`bevy_hao::cpu::OverlapKind`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct GrazeSplit {
    /// Ground-truth voxels that the surface only grazes (touches, or enters less than 1/1000 cell deep),
    /// which a point inside a sub-triangle practically never lands in. Common when faces lie on cell faces
    /// or run through cell edges, as in shapes with simple coordinates on a fitted grid; rare on scans.
    pub grazed_voxels: u64,
    /// Missing voxels among those.
    pub missing_grazed: u64,
}

/// Splits the missing voxels into grazed and cut ones, given the ground truth's `cut` cells (from
/// [`crate::ground_truth::ground_truth_mesh_with_cuts`]).
pub fn graze_split(result: &VoxelOccupancy, truth: &VoxelOccupancy, cut: &VoxelOccupancy) -> GrazeSplit {
    let (r, t, c) = (result.words(), truth.words(), cut.words());
    let mut split = GrazeSplit { grazed_voxels: 0, missing_grazed: 0 };
    for k in 0..t.len() {
        let grazed = t[k] & !c[k];
        split.grazed_voxels += grazed.count_ones() as u64;
        split.missing_grazed += (grazed & !r[k]).count_ones() as u64;
    }
    split
}

/// Compares a result with the ground truth (same grid dimensions).
pub fn compare(result: &VoxelOccupancy, truth: &VoxelOccupancy) -> Comparison {
    Comparison {
        result_voxels: result.set_voxel_count(),
        truth_voxels: truth.set_voxel_count(),
        missing: truth.count_not_in(result),
        excess: result.count_not_in(truth),
    }
}

/// The six-direction watertight ray test of the paper's section 4.1.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct WatertightReport {
    /// Voxels enclosed by the mesh (empty in the ground truth and not reachable from outside the grid
    /// without crossing it). Zero for an open mesh, for which the test has nothing to check.
    pub interior_voxels: u64,
    /// Axis-aligned rays cast that have enclosed voxels on their way (one per grid column and direction).
    pub rays: u64,
    /// Rays that reach an enclosed voxel before any voxel of the result: they went through a gap.
    pub leaks: u64,
}

impl WatertightReport {
    /// No ray leaked.
    pub fn is_watertight(&self) -> bool {
        self.leaks == 0
    }

    /// Whether the mesh encloses anything (if not, the test is vacuous).
    pub fn applies(&self) -> bool {
        self.interior_voxels > 0
    }
}

/// The voxels enclosed by the ground truth's surface: flood fill (6-connected) from the empty voxels on the
/// grid's boundary through empty voxels; what the fill does not reach is enclosed. A conservative surface
/// voxelization of a closed mesh separates inside from outside under 6-connectivity, so this is the set of
/// voxels inside the mesh (up to the surface's own voxels).
pub fn enclosed_voxels(truth: &VoxelOccupancy) -> VoxelOccupancy {
    let grid = *truth.grid();
    let d = grid.dims;
    let outside = VoxelOccupancy::new(grid, false);
    let mut stack: Vec<u32> = Vec::new();
    let visit = |i: u32, stack: &mut Vec<u32>| {
        if !truth.is_set_index(i) && !outside.is_set_index(i) {
            outside.set(grid.cell_of_index(i));
            stack.push(i);
        }
    };
    for z in 0..d.z {
        for y in 0..d.y {
            for x in 0..d.x {
                if x == 0 || y == 0 || z == 0 || x + 1 == d.x || y + 1 == d.y || z + 1 == d.z {
                    visit(grid.linear_index(UVec3::new(x, y, z)), &mut stack);
                }
            }
        }
    }
    while let Some(i) = stack.pop() {
        let c = grid.cell_of_index(i);
        if c.x > 0 {
            visit(i - 1, &mut stack);
        }
        if c.x + 1 < d.x {
            visit(i + 1, &mut stack);
        }
        if c.y > 0 {
            visit(i - d.x, &mut stack);
        }
        if c.y + 1 < d.y {
            visit(i + d.x, &mut stack);
        }
        if c.z > 0 {
            visit(i - d.x * d.y, &mut stack);
        }
        if c.z + 1 < d.z {
            visit(i + d.x * d.y, &mut stack);
        }
    }
    let words: Vec<u32> = truth.words().iter().zip(outside.words()).map(|(t, o)| !(t | o)).collect();
    VoxelOccupancy::from_words(grid, &words, None).expect("same grid")
}

/// Shoots rays through every grid column along +-x, +-y and +-z and checks that each is stopped by a voxel
/// of the result before it reaches a voxel enclosed by the mesh ([`enclosed_voxels`]).
///
/// The paper checks that the first voxel a ray hits lies within one cell of the mesh surface. Every voxel a
/// result without excess voxels sets overlaps a triangle, so that check can only fail for a ray that hits
/// nothing or passes into the mesh; testing for the passage into the mesh's enclosed voxels makes that
/// exact, and it does not flag rays that merely graze the surface and leave again.
pub fn watertight(result: &VoxelOccupancy, truth: &VoxelOccupancy) -> WatertightReport {
    let dims = truth.grid().dims;
    assert_eq!(dims, result.grid().dims, "occupancy grids of different dimensions");
    let inside = enclosed_voxels(truth);
    let mut report = WatertightReport { interior_voxels: inside.set_voxel_count(), ..Default::default() };
    if report.interior_voxels == 0 {
        return report;
    }
    for axis in 0..3 {
        let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
        let columns = (dims[u] * dims[v]) as usize;
        // Per column: the smallest and largest index along `axis` of a set voxel (u32::MAX / none).
        let extremes = |occ: &VoxelOccupancy| {
            let mut first = vec![u32::MAX; columns];
            let mut last = vec![None::<u32>; columns];
            occ.for_each_set_index(|i| {
                let c = occ.grid().cell_of_index(i);
                let col = (c[u] + dims[u] * c[v]) as usize;
                first[col] = first[col].min(c[axis]);
                last[col] = Some(last[col].map_or(c[axis], |l| l.max(c[axis])));
            });
            (first, last)
        };
        let (inside_first, inside_last) = extremes(&inside);
        let (result_first, result_last) = extremes(result);
        for col in 0..columns {
            let Some(il) = inside_last[col] else { continue };
            report.rays += 2;
            // Along +axis the ray meets the smallest index first; along -axis the largest.
            if inside_first[col] < result_first[col] {
                report.leaks += 1;
            }
            if result_last[col].is_none_or(|rl| il > rl) {
                report.leaks += 1;
            }
        }
    }
    report
}

/// How far a pixel's AO must lie from the median of its eight neighbours to count as a speck ([`specks`]).
pub const SPECK_STEP: f32 = 0.1;

/// The isolated specks of an AO image of `width` columns against its `reference`: the pixels that lie more
/// than [`SPECK_STEP`] below (dark) or above (light) the median of their eight neighbours where the
/// reference's pixel lies less than half that from its own neighbours' median (a crease or an edge the
/// reference shows is not a speck). Only pixels whose eight neighbours all show geometry (`geometry`)
/// count. Returns (dark, light).
pub fn specks(image: &[f32], reference: &[f32], width: usize, geometry: impl Fn(usize) -> bool) -> (usize, usize) {
    let height = image.len() / width.max(1);
    let step = |img: &[f32], x: usize, y: usize| {
        let mut n: Vec<f32> =
            (0..9).filter(|&k| k != 4).map(|k| img[(y + k / 3 - 1) * width + x + k % 3 - 1]).collect();
        n.sort_by(f32::total_cmp);
        img[y * width + x] - 0.5 * (n[3] + n[4])
    };
    let (mut dark, mut light) = (0, 0);
    for y in 1..height.saturating_sub(1) {
        for x in 1..width.saturating_sub(1) {
            if !(0..9).all(|k| geometry((y + k / 3 - 1) * width + x + k % 3 - 1)) {
                continue;
            }
            let (d, r) = (step(image, x, y), step(reference, x, y));
            if d < -SPECK_STEP && r > -0.5 * SPECK_STEP {
                dark += 1;
            } else if d > SPECK_STEP && r < 0.5 * SPECK_STEP {
                light += 1;
            }
        }
    }
    (dark, light)
}

#[cfg(test)]
mod speck_tests {
    #[test]
    fn a_lone_pixel_off_its_neighbours_is_a_speck_and_a_crease_the_reference_shows_is_not() {
        let (w, h) = (5, 5);
        let reference = vec![0.8f32; w * h];
        let mut image = reference.clone();
        image[2 * w + 2] = 0.6;
        image[w + 1] = 0.95;
        assert_eq!(super::specks(&image, &reference, w, |_| true), (1, 1));
        // The same dark pixel where the reference is dark too: a contact, not a speck.
        let mut dark_reference = reference.clone();
        dark_reference[2 * w + 2] = 0.6;
        assert_eq!(super::specks(&image, &dark_reference, w, |_| true), (0, 1));
        // Beside the background, nothing is counted.
        assert_eq!(super::specks(&image, &reference, w, |i| i != 0), (1, 0));
        // A line of dark pixels the reference lacks is no speck: its neighbours' median is dark too.
        let mut line = reference.clone();
        for x in 0..w {
            line[2 * w + x] = 0.6;
            line[3 * w + x] = 0.6;
        }
        assert_eq!(super::specks(&line, &reference, w, |_| true), (0, 0));
    }
}
