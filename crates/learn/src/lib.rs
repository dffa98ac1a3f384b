//! Training of the learned shape-adaptive BSSRDF (docs/model.md §5–§6): training data made by our
//! own random walks, the conditional VAE + absorption network trained with a hand-written
//! backward pass on the same `gemm`-based MLP code that inference uses, Adam, checkpoints.
//!
//! * [`sample`]: one training sample (the record of the samples file).
//! * [`walk`]: random walks inside the fitted cubic polynomial surface (exact medium physics);
//!   re-exported from [`bssrdf::walk`], where the renderer's walk sampler also uses them.
//! * [`datagen`]: configurations (shape, medium, incident point and direction), the per-configuration
//!   fit, absorption probability; parallel and seeded.
//! * [`samplefile`]: the documented binary samples file with its header.
//! * [`mlp_grad`]: backward pass of dense layers and MLPs on `gemm`.
//! * [`cvae`]: the losses of docs/model.md §6 and their gradients for the whole model.
//! * [`energy`]: the energy-score objective of the decoder (engression), a fine-tuning stage
//!   that fits the decoder's exit distribution directly.
//! * [`optim`]: Adam with staircase decay and global-norm clipping.
//! * [`train`]: the training loop, validation, checkpoints and resume.
//! * [`plot`]: loss curves.

pub mod cvae;
pub mod datagen;
pub mod energy;
pub mod fit;
pub mod mlp_grad;
/// Adam lives in `base`, shared with the inverse loop.
pub use base::optim;
pub mod plot;
pub mod sample;
pub mod samplefile;
pub mod train;
pub use bssrdf::walk;
