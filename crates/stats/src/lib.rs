//! Statistics shared by every estimator of the workspace and by the exact wave solver: random
//! streams and their seeds, matrix estimates with standard errors, batch-means accumulation of
//! `sum w a b^H` by blocked GEMM, empirical moments of sampled fields, and the deterministic
//! batch driver.
//!
//! Design decision: everything that makes a render reproducible and its error bars honest lives
//! here, once. A render draws path (or configuration) `n` from the counter-based stream
//! [`rng::PathRng::new`]`(seed, n)`, cuts its work into batches that depend only on the path
//! count ([`Batches`]), runs them on any number of threads and merges their sums in batch order
//! ([`run_ordered`]); so the same seed gives bitwise the same numbers for any thread count.
//! Standard errors come from batch means ([`Moments`]). A run can be cut into shards
//! ([`shard`]) that keep each unit's own result and merge into bitwise the single run.

#![forbid(unsafe_code)]
#![deny(missing_docs)]

mod block;
mod driver;
mod empirical;
pub mod jackknife;
mod matrix;
mod moments;
mod reduction;
pub use speckle_rng as rng;
pub mod shard;

pub use block::{BLOCK_COLUMNS, GeneralBlock, HermitianBlock, rank1_general, rank1_upper};
pub use driver::{
    Batches, MomentsRun, NoProgress, POLL_INTERVAL, PartGroups, Poll, Progress, TARGET_BATCHES,
    batch_moments, batch_moments_grouped, check_threads, for_each_path, max_threads, run_moments,
    run_ordered, run_ordered_range,
};
pub use empirical::{EmpiricalMoments, empirical_moments};
pub use matrix::{CMatrix, MatrixEstimate};
pub use moments::{BatchSum, Buffers, Layout, Moments};
pub use reduction::{BatchSums, MomentsReduction, MomentsSpec, PartialMoments};
pub use rng::PathRng;
pub use shard::{PairShare, PartialRows, Shard, ShardError, assemble_rows};

/// Errors of the statistics layer.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum StatsError {
    /// An input is invalid; `field` names it.
    #[error("{field}: {reason}")]
    InvalidInput {
        /// The offending field.
        field: String,
        /// What is wrong with it.
        reason: String,
    },
}
