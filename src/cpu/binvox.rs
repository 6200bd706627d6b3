//! The binvox format (Patrick Min's `binvox`, read by viewvox, Blender add-ons, trimesh, binvox-rw...).
//!
//! ```text
//! #binvox 1
//! dim D D D
//! translate tx ty tz
//! scale s
//! data
//! <run-length pairs of bytes: value (0 or 1), count (1..=255)>
//! ```
//!
//! The grid is a cube of `D^3` voxels in binvox order: x slowest, then z, y fastest (index
//! `x * D * D + z * D + y`). Voxel `(x, y, z)` covers `translate + (x, y, z) * scale / D` to one step more.
//! A [`VoxelOccupancy`] with per-axis dimensions is written with `D` = its longest axis, padded with empty
//! voxels, `translate` = the grid origin and `scale` = `D * cell_size`.

use super::grid::{VoxelGrid, VoxelOccupancy};
use glam::{UVec3, Vec3};
use std::io::{self, BufRead, Write};

/// A binvox grid as read from a file.
#[derive(Debug, Clone, PartialEq)]
pub struct Binvox {
    /// Voxels per axis.
    pub dim: UVec3,
    /// World position of the grid's min corner.
    pub translate: Vec3,
    /// World size of the grid's longest axis.
    pub scale: f32,
    /// Occupancy in binvox order (x slowest, then z, y fastest).
    pub voxels: Vec<bool>,
}

impl Binvox {
    /// Whether voxel `(x, y, z)` is set.
    pub fn get(&self, x: u32, y: u32, z: u32) -> bool {
        let (dy, dz) = (self.dim.y as usize, self.dim.z as usize);
        self.voxels[x as usize * dz * dy + z as usize * dy + y as usize]
    }

    /// Number of set voxels.
    pub fn set_count(&self) -> usize {
        self.voxels.iter().filter(|v| **v).count()
    }

    /// The voxels as an occupancy grid on the cubic grid the file describes.
    pub fn to_occupancy(&self) -> Result<VoxelOccupancy, crate::cpu::GridError> {
        let cell = self.scale / self.dim.max_element() as f32;
        let grid = VoxelGrid::new(self.translate, cell, self.dim)?;
        let occ = VoxelOccupancy::new(grid, false);
        for x in 0..self.dim.x {
            for z in 0..self.dim.z {
                for y in 0..self.dim.y {
                    if self.get(x, y, z) {
                        occ.set(UVec3::new(x, y, z));
                    }
                }
            }
        }
        Ok(occ)
    }
}

/// Writes an occupancy grid as binvox (see the module docs for the layout).
pub fn write_binvox(occ: &VoxelOccupancy, out: &mut impl Write) -> io::Result<()> {
    let grid = occ.grid();
    let d = grid.dims.max_element();
    writeln!(out, "#binvox 1")?;
    writeln!(out, "dim {d} {d} {d}")?;
    writeln!(out, "translate {} {} {}", grid.origin.x, grid.origin.y, grid.origin.z)?;
    writeln!(out, "scale {}", d as f32 * grid.cell_size)?;
    writeln!(out, "data")?;
    let mut run_value = 0u8;
    let mut run_len = 0u8;
    let mut bytes = Vec::with_capacity(1 << 16);
    let mut push = |value: u8, bytes: &mut Vec<u8>| {
        if value == run_value && run_len < 255 {
            run_len += 1;
        } else {
            if run_len > 0 {
                bytes.extend_from_slice(&[run_value, run_len]);
            }
            run_value = value;
            run_len = 1;
        }
    };
    for x in 0..d {
        for z in 0..d {
            for y in 0..d {
                let inside = x < grid.dims.x && y < grid.dims.y && z < grid.dims.z;
                push(u8::from(inside && occ.is_set(UVec3::new(x, y, z))), &mut bytes);
            }
            if bytes.len() >= 1 << 16 {
                out.write_all(&bytes)?;
                bytes.clear();
            }
        }
    }
    if run_len > 0 {
        bytes.extend_from_slice(&[run_value, run_len]);
    }
    out.write_all(&bytes)
}

/// Reads a binvox file.
pub fn read_binvox(input: &mut impl BufRead) -> io::Result<Binvox> {
    let bad = |msg: String| io::Error::new(io::ErrorKind::InvalidData, msg);
    let mut line = String::new();
    input.read_line(&mut line)?;
    if !line.starts_with("#binvox") {
        return Err(bad(format!("not a binvox file (first line {line:?})")));
    }
    let (mut dim, mut translate, mut scale) = (None, Vec3::ZERO, 1.0f32);
    loop {
        line.clear();
        if input.read_line(&mut line)? == 0 {
            return Err(bad("binvox header ends before 'data'".into()));
        }
        let mut words = line.split_whitespace();
        let nums = |words: std::str::SplitWhitespace| -> io::Result<Vec<f32>> {
            words.map(|w| w.parse::<f32>().map_err(|e| bad(format!("bad number {w:?}: {e}")))).collect()
        };
        match words.next() {
            Some("dim") => {
                let v = nums(words)?;
                if v.len() != 3 || v.iter().any(|x| *x < 1.0) {
                    return Err(bad(format!("bad dim line {line:?}")));
                }
                dim = Some(UVec3::new(v[0] as u32, v[1] as u32, v[2] as u32));
            }
            Some("translate") => {
                let v = nums(words)?;
                if v.len() != 3 {
                    return Err(bad(format!("bad translate line {line:?}")));
                }
                translate = Vec3::new(v[0], v[1], v[2]);
            }
            Some("scale") => scale = *nums(words)?.first().ok_or_else(|| bad("empty scale".into()))?,
            Some("data") => break,
            _ => {}
        }
    }
    let dim = dim.ok_or_else(|| bad("binvox header without dim".into()))?;
    let total = dim.x as usize * dim.y as usize * dim.z as usize;
    let mut data = Vec::new();
    input.read_to_end(&mut data)?;
    let mut voxels = Vec::with_capacity(total);
    for pair in data.chunks_exact(2) {
        voxels.extend(std::iter::repeat_n(pair[0] != 0, pair[1] as usize));
    }
    if voxels.len() != total {
        return Err(bad(format!("binvox data holds {} voxels, dim says {total}", voxels.len())));
    }
    Ok(Binvox { dim, translate, scale, voxels })
}
