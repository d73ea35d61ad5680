//! Adaptations that run between steps and change which scheme (or phase) each node has: the
//! adaptive hybrid's switching (`hybrid`, filtered by `motion`), the fixed hybrid of corrosion
//! scenes (`fixed`), the phase change (`phase`), the multi-grid coupling (`multigrid`) and its
//! adaptive form for fracture (`multiadaptive`, its fine lattice `fine_lattice`), the bond-stretch check both switches run
//! (`bonds`), and the typed masks they keep (`masks`).

pub mod bonds;
mod fine_lattice;
pub mod fixed;
pub mod hybrid;
pub mod interface;
pub mod lattice_paths;
pub mod masks;
pub mod motion;
pub mod multiadaptive;
pub mod multigrid;
pub mod phase;
pub mod splitting;
