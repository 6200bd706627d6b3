//! Tests of the voxelizers against each other and against the ground truth.

use bevy_hao::cpu::*;
use bevy_hao_tools::meshes::{CLOSED_BUILTINS, builtin};
use bevy_hao_tools::*;
use glam::{Affine3A, UVec3, Vec3};

/// A small deterministic generator (splitmix64), so that failures reproduce.
struct Rng(u64);

impl Rng {
    fn new(seed: u64) -> Self {
        Self(seed)
    }
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in `[lo, hi)`.
    fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * ((self.next_u64() >> 40) as f32 / (1u64 << 24) as f32)
    }
    fn vec3(&mut self, lo: f32, hi: f32) -> Vec3 {
        Vec3::new(self.range(lo, hi), self.range(lo, hi), self.range(lo, hi))
    }
}

/// Random triangles of every size class in and around a `dims` grid: sub-voxel, a few cells, grid-spanning
/// and sticking out of the grid.
fn random_triangles(rng: &mut Rng, count: usize, dims: f32) -> TriangleMesh {
    let mut m = TriangleMesh::default();
    for k in 0..count {
        let size = match k % 4 {
            0 => 0.3,
            1 => 2.5,
            2 => dims * 0.6,
            _ => dims * 1.5,
        };
        let c = rng.vec3(-0.1 * dims, 1.1 * dims);
        let b = m.positions.len() as u32;
        for _ in 0..3 {
            m.positions.push(c + rng.vec3(-size, size));
        }
        m.triangles.push([b, b + 1, b + 2]);
    }
    m
}

fn grid(dims: UVec3) -> VoxelGrid {
    VoxelGrid::new(Vec3::ZERO, 1.0, dims).unwrap()
}

fn truth_of(mesh: &TriangleMesh, g: &VoxelGrid) -> VoxelOccupancy {
    let t = VoxelOccupancy::new(*g, false);
    ground_truth_mesh(mesh, g.grid_from_world(), &t);
    t
}

fn run(mesh: &TriangleMesh, g: &VoxelGrid, mode: InjectionMode, gamma: f32) -> (VoxelOccupancy, VoxelizeStats) {
    voxelize(mesh, g, &VoxelizeSettings { gamma, mode, ..Default::default() })
}

#[test]
fn every_voxel_set_is_overlapped_by_a_triangle_and_conservative_mode_equals_the_ground_truth() {
    let mut rng = Rng::new(7);
    for round in 0..6 {
        let dims = UVec3::new(24 + 5 * round, 17, 31);
        let mesh = random_triangles(&mut rng, 400, 24.0);
        let g = grid(dims);
        let truth = truth_of(&mesh, &g);
        for gamma in [1.0, 2.5] {
            let (centroid, stats) = run(&mesh, &g, InjectionMode::Centroid, gamma);
            let c = compare(&centroid, &truth);
            // Ties: a centroid computed a few ulp off a cell face can land in a cell the triangle does not
            // reach. None are expected at these magnitudes; allow one in 10^4 set voxels before failing.
            assert!(c.excess * 10_000 <= c.result_voxels, "round {round}: {c:?}");
            assert!(stats.injected > 0);
            let (cons, _) = run(&mesh, &g, InjectionMode::Conservative, gamma);
            let k = compare(&cons, &truth);
            assert_eq!((k.missing, k.excess), (0, 0), "round {round}, gamma {gamma}: {k:?}");
            // Centroid mode finds a subset of conservative mode.
            assert_eq!(centroid.count_not_in(&cons), c.excess);
        }
    }
}

#[test]
fn bias_falls_as_gamma_grows() {
    // Large triangles over a fine grid, where centroid injection misses the most.
    let mesh = builtin("sphere").unwrap();
    let (lo, hi) = mesh.bounds().unwrap();
    let g = VoxelGrid::fit_to_bounds(lo, hi, 96).unwrap();
    let truth = truth_of(&mesh, &g);
    let bias: Vec<f64> = [1.0, 2.0, 4.0]
        .iter()
        .map(|&gamma| compare(&voxelize(&mesh, &g, &VoxelizeSettings { gamma, ..Default::default() }).0, &truth).bias())
        .collect();
    assert!(bias[0] > bias[1] && bias[1] > bias[2], "{bias:?}");
    assert!(bias[0] > 0.0);
}

/// Bias bounds at gamma = 1 for the built-in meshes at 64^3. The paper's 1.7-4.4 % is for meshes of up to 7
/// million triangles, mostly smaller than a voxel; these meshes have few, large triangles, so every cell
/// the surface only clips is at stake and the measured bias is 10-25 % (1 % for the cathedral's boxes).
/// Each bound sits between the bias measured at gamma = 1 and at gamma = 0.7 (a pattern 30 % coarser than
/// equation 1 asks, which this test also runs to show the bound can fail): it catches a subdivision that
/// is coarser than it should be or a pattern with gaps, and leaves room for harmless changes of rounding.
#[test]
fn bias_at_gamma_one_is_bounded_for_every_builtin_mesh() {
    for (name, bound) in [
        ("windmill", 0.21),
        ("pyramid", 0.25),
        ("chamfer-box", 0.22),
        ("star", 0.13),
        ("tetrahedron", 0.25),
        ("sphere", 0.28),
        ("torus", 0.20),
        ("cathedral", 0.015),
    ] {
        let mesh = builtin(name).unwrap();
        let (lo, hi) = mesh.bounds().unwrap();
        let g = VoxelGrid::fit_to_bounds(lo, hi, 64).unwrap();
        let truth = truth_of(&mesh, &g);
        let (result, _) = run(&mesh, &g, InjectionMode::Centroid, 1.0);
        let c = compare(&result, &truth);
        let coarse = compare(&run(&mesh, &g, InjectionMode::Centroid, 0.7).0, &truth);
        println!(
            "{name}: bias {:.2}% (gamma 0.7: {:.2}%) excess {}",
            100.0 * c.bias(),
            100.0 * coarse.bias(),
            c.excess
        );
        assert!(c.bias() < bound, "{name}: bias {:.3} over {bound}", c.bias());
        assert!(coarse.bias() > bound, "{name}: the bound does not tell gamma 0.7 from 1");
        assert_eq!(c.excess, 0, "{name}");
    }
}

#[test]
fn grazed_voxels_explain_the_bias_that_gamma_cannot_remove() {
    let split_at = |name: &str, gamma: f32| {
        let mesh = builtin(name).unwrap();
        let (lo, hi) = mesh.bounds().unwrap();
        let g = VoxelGrid::fit_to_bounds(lo, hi, 64).unwrap();
        let truth = VoxelOccupancy::new(g, false);
        let cut = VoxelOccupancy::new(g, false);
        ground_truth::ground_truth_mesh_with_cuts(&mesh, g.grid_from_world(), &truth, Some(&cut));
        let (result, _) = run(&mesh, &g, InjectionMode::Centroid, gamma);
        (compare(&result, &truth), graze_split(&result, &truth, &cut))
    };
    // The chamfer box's chamfers run (within rounding) through the cell edges of its fitted grid: what
    // centroid injection misses at any gamma is only voxels that the surface grazes.
    for gamma in [1.0, 2.0, 4.0] {
        let (c, split) = split_at("chamfer-box", gamma);
        assert!(c.missing > 0);
        assert_eq!(split.missing_grazed, c.missing, "gamma {gamma}");
    }
    // A sphere's misses at gamma = 1 are mostly cells its surface cuts through, and those go as gamma grows.
    let cut_missing = |gamma| {
        let (c, split) = split_at("sphere", gamma);
        c.missing - split.missing_grazed
    };
    assert!(cut_missing(1.0) > 2 * cut_missing(4.0));
}

#[test]
fn closed_builtin_meshes_voxelize_watertight() {
    for name in CLOSED_BUILTINS {
        let mesh = builtin(name).unwrap();
        let (lo, hi) = mesh.bounds().unwrap();
        for res in [32, 100] {
            let g = VoxelGrid::fit_to_bounds(lo, hi, res).unwrap();
            let truth = truth_of(&mesh, &g);
            let (result, _) = run(&mesh, &g, InjectionMode::Centroid, 1.0);
            let w = watertight(&result, &truth);
            assert!(w.rays > 0);
            assert!(w.applies() && w.is_watertight(), "{name} at {res}: {w:?}");
        }
    }
}

#[test]
fn the_watertight_test_catches_a_hole() {
    let mesh = builtin("sphere").unwrap();
    let (lo, hi) = mesh.bounds().unwrap();
    let g = VoxelGrid::fit_to_bounds(lo, hi, 32).unwrap();
    let truth = truth_of(&mesh, &g);
    // Drop the triangles around the north pole: rays along -y then pass through to the far side.
    let mut holed = mesh.clone();
    holed.triangles.retain(|t| t.iter().all(|&i| mesh.positions[i as usize].y < 0.9));
    let (result, _) = run(&holed, &g, InjectionMode::Centroid, 1.0);
    assert!(!watertight(&result, &truth).is_watertight());
}

#[test]
fn builtin_closed_meshes_are_closed_and_outward() {
    for name in CLOSED_BUILTINS.iter().chain(["cathedral", "apartment", "office"].iter()) {
        let parts: Vec<TriangleMesh> = if *name == "cathedral" {
            bevy_hao_tools::meshes::cathedral_parts().into_iter().map(|p| p.1).collect()
        } else {
            vec![builtin(name).unwrap()]
        };
        for mesh in parts {
            // (Solids are appended without welding, so index-based edges stay within each solid.)
            // Every directed edge appears once and its reverse once.
            let mut edges = std::collections::HashMap::new();
            for t in &mesh.triangles {
                for k in 0..3 {
                    *edges.entry((t[k], t[(k + 1) % 3])).or_insert(0) += 1;
                }
            }
            for (&(a, b), &n) in &edges {
                assert_eq!(n, 1, "{name}: edge {a}-{b} used {n} times in one direction");
                assert_eq!(edges.get(&(b, a)), Some(&1), "{name}: edge {a}-{b} has no twin");
            }
            let volume: f32 = mesh
                .triangles
                .iter()
                .map(|t| {
                    let [a, b, c] = t.map(|i| mesh.positions[i as usize]);
                    a.dot(b.cross(c)) / 6.0
                })
                .sum();
            assert!(volume > 0.0, "{name}: signed volume {volume}");
        }
    }
}

#[test]
fn bad_triangles_are_skipped_and_counted_without_panics() {
    let g = grid(UVec3::splat(8));
    let nan = f32::NAN;
    let inf = f32::INFINITY;
    let mesh = TriangleMesh::new(
        vec![
            Vec3::new(1.0, 1.0, 1.0),
            Vec3::new(5.0, 1.0, 1.0),
            Vec3::new(1.0, 5.0, 1.0),
            Vec3::new(nan, 1.0, 1.0),
            Vec3::new(inf, 1.0, 1.0),
            Vec3::new(3.0, 1.0, 1.0), // collinear with 0 and 1
        ],
        vec![
            [0, 1, 2],  // fine
            [0, 1, 3],  // NaN vertex
            [0, 4, 2],  // inf vertex
            [0, 1, 5],  // zero area (collinear)
            [2, 2, 2],  // zero area (one point)
            [0, 1, 99], // index out of range
        ],
    );
    for mode in [InjectionMode::Centroid, InjectionMode::Conservative] {
        let (occ, stats) = run(&mesh, &g, mode, 1.0);
        assert_eq!(stats.triangles, 6);
        assert_eq!(stats.invalid, 3, "{mode}");
        assert_eq!(stats.degenerate, 2, "{mode}");
        let only_good = TriangleMesh::new(mesh.positions[..3].to_vec(), vec![[0, 1, 2]]);
        assert_eq!(occ.words(), run(&only_good, &g, mode, 1.0).0.words(), "{mode}");
    }
    let t = VoxelOccupancy::new(g, false);
    let gt = ground_truth_mesh(&mesh, g.grid_from_world(), &t);
    assert_eq!(gt.skipped, 5);
}

#[test]
fn huge_and_outside_triangles_are_clipped_to_the_grid() {
    let g = grid(UVec3::new(16, 8, 16));
    // A floor triangle 40 km across at y = 3.5 covering the grid, and one wholly outside.
    let mesh = TriangleMesh::new(
        vec![
            Vec3::new(-1.0e4, 3.5, -1.0e4),
            Vec3::new(3.0e4, 3.5, -1.0e4),
            Vec3::new(-1.0e4, 3.5, 3.0e4),
            Vec3::new(100.0, 1.0, 1.0),
            Vec3::new(101.0, 1.0, 1.0),
            Vec3::new(100.0, 2.0, 1.0),
        ],
        vec![[0, 1, 2], [3, 4, 5]],
    );
    for mode in [InjectionMode::Centroid, InjectionMode::Conservative] {
        let (occ, stats) = run(&mesh, &g, mode, 1.0);
        assert_eq!(stats.outside, 1);
        assert_eq!(stats.oversize, 0);
        // n = 40000: the full lattice would be 1.6 * 10^9 sub-triangles; clipping keeps a few hundred.
        assert!(stats.sub_triangles < 2_000, "{stats:?}");
        // The whole y = 3 layer is set, nothing else.
        assert_eq!(occ.set_voxel_count(), 16 * 16, "{mode}");
        assert!(occ.is_set(UVec3::new(15, 3, 15)) && occ.is_set(UVec3::new(0, 3, 0)));
        let truth = truth_of(&mesh, &g);
        assert_eq!(compare(&occ, &truth).missing, 0);
    }
}

#[test]
fn clipping_does_not_change_what_lands_inside() {
    // The same random triangles voxelized in a small grid and in a larger one that contains them whole,
    // offset by whole cells: inside the small grid the results must agree.
    let mut rng = Rng::new(11);
    let mesh = random_triangles(&mut rng, 300, 16.0);
    let small = grid(UVec3::splat(16));
    let big = VoxelGrid::new(Vec3::splat(-64.0), 1.0, UVec3::splat(160)).unwrap();
    for mode in [InjectionMode::Centroid, InjectionMode::Conservative] {
        let (a, _) = run(&mesh, &small, mode, 1.0);
        let (b, _) = run(&mesh, &big, mode, 1.0);
        let mut differ = 0;
        for cell in ground_truth::cells_in(UVec3::ZERO, UVec3::splat(15)) {
            differ += u32::from(a.is_set(cell) != b.is_set(cell + UVec3::splat(64)));
        }
        // Grid-space coordinates differ by 64 between the two, which changes rounding: allow a handful.
        assert!(differ <= 3, "{mode}: {differ} voxels differ");
    }
}

#[test]
fn point_counts_add_up() {
    let mesh = builtin("torus").unwrap();
    let (lo, hi) = mesh.bounds().unwrap();
    let g = VoxelGrid::fit_to_bounds(lo, hi, 48).unwrap();
    let (occ, stats) = run(&mesh, &g, InjectionMode::Centroid, 1.0);
    assert_eq!(occ.total_count(), stats.injected);
    assert_eq!(stats.injected, stats.sub_triangles);
    // Every set voxel has a point, every voxel with a point is set.
    occ.for_each_set_index(|i| assert!(occ.count(g.cell_of_index(i)) > 0));
    assert!(occ.max_count() >= 1);
}

#[test]
fn transforms_are_applied_before_voxelizing() {
    let mesh = builtin("tetrahedron").unwrap();
    let g = VoxelGrid::new(Vec3::splat(-4.0), 0.25, UVec3::splat(32)).unwrap();
    let world = Affine3A::from_scale_rotation_translation(
        Vec3::splat(1.5),
        glam::Quat::from_rotation_y(0.7),
        Vec3::new(0.5, 0.2, -0.3),
    );
    let a = VoxelOccupancy::new(g, false);
    voxelize_mesh(&mesh, g.grid_from_world() * world, &VoxelizeSettings::default(), &a);
    let (b, _) = voxelize(&mesh.transformed(world), &g, &VoxelizeSettings::default());
    let diff = a.count_not_in(&b) + b.count_not_in(&a);
    assert!(diff <= 2, "{diff}");
    assert!(a.set_voxel_count() > 100);
}

#[test]
fn binvox_round_trips() {
    let mesh = builtin("star").unwrap();
    let (lo, hi) = mesh.bounds().unwrap();
    let g = VoxelGrid::fit_to_bounds(lo, hi, 40).unwrap();
    let (occ, _) = voxelize(&mesh, &g, &VoxelizeSettings::default());
    assert!(g.dims.y < g.dims.x, "non-cubic on purpose");
    let mut bytes = Vec::new();
    write_binvox(&occ, &mut bytes).unwrap();
    let read = read_binvox(&mut std::io::Cursor::new(bytes)).unwrap();
    assert_eq!(read.dim, UVec3::splat(40));
    assert_eq!(read.translate, g.origin);
    assert!((read.scale - 40.0 * g.cell_size).abs() < 1e-6);
    assert_eq!(read.set_count() as u64, occ.set_voxel_count());
    let back = read.to_occupancy().unwrap();
    for cell in occ.set_cells() {
        assert!(back.is_set(cell));
    }
    assert!(read_binvox(&mut std::io::Cursor::new(b"#binvox 1\ndim 2 2 2\ndata\n\x00\x07".to_vec())).is_err());
}

/// The largest distance, in cells, from a set voxel's centre to the sphere of `radius` about the origin,
/// and the largest distance from a point of the sphere (10,000 spread evenly) to the nearest set voxel's
/// centre, searched within two cells.
fn sphere_distances(occ: &VoxelOccupancy, radius: f32) -> (f32, f32) {
    let g = *occ.grid();
    let mut off = 0.0f32;
    occ.for_each_set_index(|i| {
        let d = (g.cell_center_world(g.cell_of_index(i)).length() - radius).abs() / g.cell_size;
        off = off.max(d);
    });
    let mut gap = 0.0f32;
    let n = 10_000;
    for k in 0..n {
        // A Fibonacci lattice on the sphere.
        let y = 1.0 - 2.0 * (k as f32 + 0.5) / n as f32;
        let phi = k as f32 * std::f32::consts::PI * (3.0 - 5.0f32.sqrt());
        let r = (1.0 - y * y).sqrt();
        let p = Vec3::new(r * phi.cos(), y, r * phi.sin()) * radius;
        let c = g.world_to_grid(p).floor().as_ivec3();
        let mut nearest = f32::INFINITY;
        for dz in -2..=2 {
            for dy in -2..=2 {
                for dx in -2..=2 {
                    let cell = c + glam::IVec3::new(dx, dy, dz);
                    if cell.cmpge(glam::IVec3::ZERO).all()
                        && cell.cmplt(g.dims.as_ivec3()).all()
                        && occ.is_set(cell.as_uvec3())
                    {
                        nearest = nearest.min(g.cell_center_world(cell.as_uvec3()).distance(p) / g.cell_size);
                    }
                }
            }
        }
        gap = gap.max(nearest);
    }
    (off, gap)
}

/// PN triangles (Fei 2012 section 3.4): the 320-triangle icosphere voxelized at 512^3 as PN triangles is
/// round: every set voxel's centre lies within one cell of the true sphere, and every point of the sphere
/// has a set voxel centre within one cell (measured: 0.93 and 0.86 cells in centroid mode). Its flat
/// triangles sag up to 4.4 cells inside the sphere (set voxels 5.1 cells off).
/// (The 20-triangle icosahedron cannot pass: its PN patches stay 5.9% of the radius, 15 cells, inside.)
#[test]
fn pn_triangles_voxelize_a_coarse_icosphere_round() {
    let mesh = bevy_hao_tools::meshes::builtin::icosphere(1.0, 2);
    assert_eq!(mesh.triangle_count(), 320);
    let g = VoxelGrid::fit_to_bounds(Vec3::splat(-1.0), Vec3::splat(1.0), 512).unwrap();
    // The sphere's own normals, as a modeller exports them.
    let normals: Vec<Vec3> = mesh.positions.iter().map(|p| p.normalize()).collect();
    for mode in [InjectionMode::Centroid, InjectionMode::Conservative] {
        let settings = VoxelizeSettings { mode, ..Default::default() };
        let pn = VoxelOccupancy::new(g, false);
        let stats = voxelize_mesh_pn(&mesh, &normals, g.grid_from_world(), &settings, &pn);
        assert_eq!((stats.triangles, stats.invalid, stats.oversize), (320, 0, 0));
        let (off, gap) = sphere_distances(&pn, 1.0);
        // A voxel centre is up to sqrt(3)/2 from the point that set it: the patch is within 0.13 cells.
        assert!(off <= 1.0 && gap <= 1.0, "{mode:?}: PN voxels {off:.2} cells off the sphere, gaps {gap:.2}");
        let flat = VoxelOccupancy::new(g, false);
        voxelize_mesh(&mesh, g.grid_from_world(), &settings, &flat);
        let (flat_off, _) = sphere_distances(&flat, 1.0);
        assert!(flat_off > 3.0, "{mode:?}: the flat icosphere is {flat_off:.2} cells off");
    }
}

/// A mesh with no curvature voxelizes the same as PN triangles and as flat ones (the patches are the
/// triangles), here the chamfered box with its face normals.
#[test]
fn pn_triangles_of_flat_faces_change_nothing() {
    let mesh = builtin("chamfer-box").unwrap();
    let g = grid(UVec3::splat(48));
    // Off the lattice planes (a face on one puts its centroids on cell faces, where rounding decides).
    let to_grid =
        g.grid_from_world() * Affine3A::from_scale(Vec3::splat(19.7)) * Affine3A::from_translation(Vec3::splat(1.13));
    // Face normals per corner: unweld, so that each triangle's corners carry its own normal.
    let mut flat_faces = TriangleMesh::default();
    let mut normals = Vec::new();
    for t in 0..mesh.triangle_count() {
        let [a, b, c] = mesh.triangle(t).unwrap();
        let n = (b - a).cross(c - a).normalize();
        let base = flat_faces.positions.len() as u32;
        flat_faces.positions.extend([a, b, c]);
        flat_faces.triangles.push([base, base + 1, base + 2]);
        normals.extend([n; 3]);
    }
    let settings = VoxelizeSettings::default();
    let pn = VoxelOccupancy::new(g, false);
    voxelize_mesh_pn(&flat_faces, &normals, to_grid, &settings, &pn);
    let flat = VoxelOccupancy::new(g, false);
    voxelize_mesh(&flat_faces, to_grid, &settings, &flat);
    assert!(flat.set_voxel_count() > 1000);
    // Rounding in the patch's cubic may move a centroid that lies on a cell face: allow a few.
    let differ = pn.count_not_in(&flat) + flat.count_not_in(&pn);
    assert!(differ * 1000 <= flat.set_voxel_count(), "{differ} of {} voxels differ", flat.set_voxel_count());
}

/// Solid voxelization (Dong et al. 2004) against an independent inside test: on every closed built-in
/// shape, turned so that nothing lines up with the lattice, the conservative surface plus the parity fill
/// equals the surface plus the voxels a flood fill from the grid's boundary cannot reach through it; and
/// the centroid surface plus the fill covers every such voxel.
#[test]
fn solid_fill_matches_a_flood_fill_from_outside() {
    let turn = Affine3A::from_rotation_translation(
        glam::Quat::from_euler(glam::EulerRot::XYZ, 0.31, 0.77, -0.42),
        Vec3::new(0.013, -0.021, 0.007),
    );
    for name in CLOSED_BUILTINS {
        let mesh = builtin(name).unwrap().transformed(turn);
        assert_eq!(open_edge_count(&mesh), 0, "{name} is closed");
        let (lo, hi) = mesh.bounds().unwrap();
        let g = VoxelGrid::fit_to_bounds(lo, hi, 40).unwrap();
        let truth = truth_of(&mesh, &g);
        let enclosed = enclosed_voxels(&truth);
        assert!(enclosed.set_voxel_count() > 0, "{name}: nothing enclosed");
        let solid = truth_of(&mesh, &g);
        let f = fill_solid(&mesh, g.grid_from_world(), &solid);
        assert_eq!(f.odd_columns, 0, "{name}");
        assert_eq!(f.filled, enclosed.set_voxel_count(), "{name}: filled against enclosed");
        assert_eq!(enclosed.count_not_in(&solid), 0, "{name}");
        let (centroid, _) = run(&mesh, &g, InjectionMode::Centroid, 1.0);
        fill_solid(&mesh, g.grid_from_world(), &centroid);
        assert_eq!(enclosed.count_not_in(&centroid), 0, "{name}: centroid surface + fill");
    }
}

/// Equation 3 fitted on patches of the geometry (`cpu::calibrate`, what `VoxelVolume::target_bias` uses)
/// picks a gamma that meets the target on meshes it was not tuned on: the whole mesh voxelized at that gamma
/// misses at most twice the target share of the exact ground truth (and gamma 1 misses more than the target).
#[test]
fn calibrated_gamma_meets_a_target_bias_on_held_out_meshes() {
    for name in ["sphere", "torus", "icosphere", "cathedral"] {
        let mesh = builtin(name).unwrap();
        let (lo, hi) = mesh.bounds().unwrap();
        let g = VoxelGrid::fit_to_bounds(lo, hi, 96).unwrap();
        let triangles: Vec<[Vec3; 3]> = (0..mesh.triangle_count()).filter_map(|t| mesh.triangle(t)).collect();
        let calibration = calibrate(&triangles, g.cell_size, SubdivisionPattern::Strips).unwrap();
        let truth = truth_of(&mesh, &g);
        let bias_at = |gamma: f32| {
            compare(&voxelize(&mesh, &g, &VoxelizeSettings { gamma, ..Default::default() }).0, &truth).bias()
        };
        for target in [0.05, 0.02] {
            let gamma = calibration.gamma_for_bias(target, 16.0);
            let bias = bias_at(gamma);
            println!("{name}: target {target}, gamma {gamma:.2}, bias {bias:.4} (gamma 1: {:.4})", bias_at(1.0));
            assert!(bias <= 2.0 * target, "{name}: target {target}: gamma {gamma} gives bias {bias}");
        }
    }
}
