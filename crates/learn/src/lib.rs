//! Training of the learned shape-adaptive BSSRDF (model-spec §5–§6): training data made by our
//! own random walks, the conditional VAE + absorption network trained with a hand-written
//! backward pass on the same `gemm`-based MLP code that inference uses, Adam, checkpoints.
//!
//! * [`sample`]: one training sample (the record of the samples file).
//! * [`walk`]: random walks inside the fitted cubic polynomial surface (exact medium physics).
//! * [`datagen`]: configurations (shape, medium, incident point and direction), the per-configuration
//!   fit, absorption probability; parallel and seeded.
//! * [`samplefile`]: the documented binary samples file with its header.
//! * [`backprop`]: backward pass of dense layers and MLPs.
//! * [`vae`]: the losses of model-spec §6 and their gradients for the whole model.
//! * [`adam`]: Adam with staircase decay and global-norm clipping.
//! * [`train`]: the training loop, validation, checkpoints and resume.
//! * [`plot`]: loss curves.

pub mod adam;
pub mod backprop;
pub mod datagen;
pub mod plot;
pub mod sample;
pub mod samplefile;
pub mod train;
pub mod vae;
pub mod walk;
