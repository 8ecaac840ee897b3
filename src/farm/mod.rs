//! Splitting renders over a render farm and putting them back together.
//!
//! A render is cut into tiles (bands of rows, [`crate::render::tiles`]),
//! each written by whichever machine a scheduler (Slurm, HTCondor) gives
//! it, as an EXR of linear film that records what it is ([`record`]);
//! [`merge`] checks the tiles belong together and rebuilds the single
//! render's bytes. A [`job`] multiplies recipes, scenes, settings,
//! turntable frames and tiles into numbered tasks, one per array element.
//! Nothing here knows the scheduler: it only sees task numbers.

pub mod job;
pub mod merge;
pub mod record;
