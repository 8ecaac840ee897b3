//! Layered micro-facet BRDFs.
