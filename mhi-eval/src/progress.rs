//! Progress bars shared by the long-running tasks.

use indicatif::{ProgressBar, ProgressStyle};

/// A bar of `len` steps labelled `what`, with rate and ETA; hidden when stderr is not a terminal
/// is left to indicatif (it draws nothing then).
pub fn bar(len: u64, what: &str) -> ProgressBar {
    let pb = ProgressBar::new(len);
    pb.set_style(
        ProgressStyle::with_template(
            "{msg:>12} [{elapsed_precise}] {wide_bar} {pos}/{len} ({per_sec}, ETA {eta})",
        )
        .expect("static template is valid"),
    );
    pb.set_message(what.to_owned());
    pb
}
