#![doc = include_str!("../README.md")]
#![warn(missing_docs)]

pub mod cpu;
pub mod meshes;
