//! Additive machining onto an existing part (SPEC §5, Yamauchi & Morishige): read and validate
//! STL meshes, build the polygon frame on a chosen face of the base part, slice the added shape
//! in its local frame, fill each layer with walls and infill, transform every path onto the
//! face, check the nozzle and carriage against the base part, and hand the result to the G-code
//! writer.
//!
//! Modules, one job each:
//! - [`stl`]: reading (binary and ASCII), welding and validation of triangle meshes;
//! - [`frame`]: the polygon frame and the paper's transform `T`;
//! - [`slice`]: plane sections of a closed mesh, chained into oriented loops;
//! - [`offset`]: inward polygon offsetting for walls;
//! - [`fill`]: walls and infill of one layer;
//! - [`collision`]: nozzle cone + carriage cylinder against the base mesh;
//! - [`job`]: the whole job, from two meshes to world-space toolpaths;
//! - [`experiment`]: the paper's 15° slope and triangular pyramid.

pub mod collision;
pub mod experiment;
pub mod fill;
pub mod frame;
pub mod job;
pub mod offset;
pub mod slice;
pub mod stl;
