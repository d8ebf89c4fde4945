//! Point-based fusion (Keller et al. 2013): associate each input pixel with
//! the surfels whose centres project into it, merge or add, remove unstable
//! surfels, and predict the model for the next frame's tracker. Only the
//! map blocks inside the view frustum are visited (`chunk_bounds`,
//! `frustum`); fusion also skips blocks wholly behind the measured depth
//! (`depth_tiles`), and prediction the blocks that surface hides. Settled
//! surfels are sorted in space so that blocks are compact (`spatial_order`).
//!
//! Time in the map: each surfel keeps the frame it was created and the frame
//! it was last updated (`SurfelMap::last_seen`). Surfels not updated for
//! `FusionConfig::active_window_frames` are inactive: association and the
//! tracker's prediction read only the active ones (and skip whole blocks of
//! inactive ones), while the map, its drawing and its exports hold all of
//! them. `Prediction::render` with `FusionConfig::inactive_at` renders the
//! inactive model, which loop closure registers the active one against.
//!
//! All surfel attributes are in the world frame, metres.

pub mod chunk_bounds;
mod cleanup;
mod coincide;
mod config;
mod depth_tiles;
pub mod frustum;
pub mod index_map;
mod integrate;
mod map_state;
mod noise_weights;
pub mod predict;
mod spatial_order;
mod surfel;
mod surfel_map;

pub use cleanup::remove_unstable;
pub use coincide::merge_copies;
pub use config::FusionConfig;
pub use depth_tiles::DepthTiles;
pub use integrate::{FusionStats, Integrator, ABSORBED};
pub use map_state::MapSchedule;
pub use predict::{Measured, Prediction};
pub use spatial_order::SpatialOrder;
pub use surfel::Surfel;
pub use surfel_map::SurfelMap;
