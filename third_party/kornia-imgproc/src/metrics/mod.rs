mod huber;
mod l1;
mod mse;

pub use huber::huber;
pub use l1::l1_loss;
pub use mse::{mse, psnr};
