//! `cargo xtask weights`: [`mhi_net::weights::fetch`] into the cache.

use crate::common::cache_dir;
use crate::options::WeightsArgs;

/// `cargo xtask weights`.
pub fn weights(a: &WeightsArgs) -> anyhow::Result<()> {
    mhi_net::weights::fetch(&mhi_net::weights::FetchOptions {
        dir: cache_dir(a.cache.as_deref()).join("weights"),
        python: a.python.clone(),
        force: a.force,
    })?;
    Ok(())
}
