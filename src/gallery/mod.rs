//! Pictures made from the renderer and the BRDFs, above `render`: the
//! `lapidary gallery` sheets and the course notes' figures ([`figures`]),
//! and the plots and text they and the `brdf` and `maps` commands draw
//! ([`plot`]).

pub mod figures;
pub mod plot;
