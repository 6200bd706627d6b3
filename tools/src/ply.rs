//! The attribute sidecar of a voxel grid: multi-valued voxels ([`bevy_hao::cpu::attributes`]) as a binary
//! PLY point cloud, one vertex per voxel with points, at the voxel's world-space centre, with its average
//! normal (`nx ny nz`, length below 1 where the points' normals disagree) and its average albedo (`red green
//! blue`, bytes, sRGB-encoded as viewers expect). MeshLab, CloudCompare and Blender open it beside the
//! binvox.

use bevy_hao::cpu::VoxelOccupancy;
use std::io::{self, Write};

/// Writes the voxels of `occ` that have attributes as a binary little-endian PLY; returns how many. An
/// occupancy without attribute sums writes no vertices.
pub fn write_attribute_ply(occ: &VoxelOccupancy, out: &mut impl Write) -> io::Result<u64> {
    let grid = occ.grid();
    let mut vertices = Vec::new();
    if occ.has_attributes() {
        occ.for_each_set_index(|i| {
            let cell = grid.cell_of_index(i);
            if let Some(a) = occ.attributes(cell) {
                vertices.push((grid.cell_center_world(cell), a));
            }
        });
    }
    write!(
        out,
        "ply\nformat binary_little_endian 1.0\ncomment bevy_hao multi-valued voxels: centre, average normal, \
         average albedo (sRGB); cell size {}\nelement vertex {}\nproperty float x\nproperty float y\n\
         property float z\nproperty float nx\nproperty float ny\nproperty float nz\nproperty uchar red\n\
         property uchar green\nproperty uchar blue\nend_header\n",
        grid.cell_size,
        vertices.len()
    )?;
    for (p, a) in &vertices {
        for v in [p.x, p.y, p.z, a.normal.x, a.normal.y, a.normal.z] {
            out.write_all(&v.to_le_bytes())?;
        }
        let byte = |c: f32| (bevy::color::Srgba::gamma_function_inverse(c.clamp(0.0, 1.0)) * 255.0).round() as u8;
        out.write_all(&[byte(a.albedo.x), byte(a.albedo.y), byte(a.albedo.z)])?;
    }
    Ok(vertices.len() as u64)
}

#[cfg(test)]
mod tests {
    use super::*;
    use bevy_hao::cpu::attributes::{MeshAlbedo, pack_albedo};
    use bevy_hao::cpu::{InjectionRegion, TriangleMesh, VoxelGrid, VoxelizeSettings, voxelize_sampled_mesh_in_region};
    use glam::Vec3;

    #[test]
    fn the_sidecar_holds_one_vertex_per_voxel_with_its_averages() {
        let mesh =
            TriangleMesh::new(vec![Vec3::ZERO, Vec3::new(4.0, 0.0, 0.0), Vec3::new(0.0, 4.0, 0.0)], vec![[0, 1, 2]]);
        let grid = VoxelGrid::new(Vec3::splat(-0.5), 1.0, glam::UVec3::splat(6)).unwrap();
        let occ = VoxelOccupancy::with_attributes(grid);
        let albedo = MeshAlbedo { base: pack_albedo(Vec3::new(1.0, 0.5, 0.0)), vertex_colors: None };
        let settings = VoxelizeSettings::default();
        let region = InjectionRegion::whole(grid.dims);
        voxelize_sampled_mesh_in_region(&mesh, &albedo, grid.grid_from_world(), &settings, &region, &occ);
        let mut bytes = Vec::new();
        let n = write_attribute_ply(&occ, &mut bytes).unwrap();
        assert_eq!(n, occ.set_voxel_count());
        let header_end = bytes.windows(11).position(|w| w == b"end_header\n").unwrap() + 11;
        let header = std::str::from_utf8(&bytes[..header_end]).unwrap();
        assert!(header.contains(&format!("element vertex {n}\n")), "{header}");
        assert_eq!(bytes.len() - header_end, n as usize * 27);
        // Every vertex: normal +z (counter-clockwise in the xy plane), albedo linear (1, 0.5, 0) to a byte,
        // sRGB-encoded: (255, 188, 0).
        for v in bytes[header_end..].chunks_exact(27) {
            let f = |k: usize| f32::from_le_bytes(v[4 * k..4 * k + 4].try_into().unwrap());
            assert_eq!((f(3), f(4)), (0.0, 0.0));
            assert!((f(5) - 1.0).abs() < 1e-3);
            assert_eq!(&v[24..27], &[255, 188, 0]);
        }
        // Without attribute sums: no vertices.
        let plain = VoxelOccupancy::new(grid, true);
        assert_eq!(write_attribute_ply(&plain, &mut Vec::new()).unwrap(), 0);
    }
}
