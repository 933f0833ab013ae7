//! Headless Chromium for the viewer's tests (feature `browser`): where it is, a screenshot of
//! a page and its DOM. Test support: it panics when Chromium fails.

use std::path::{Path, PathBuf};
use std::process::Command;

/// Chromium at `$MHI_CHROMIUM` or a usual place, if there is one.
pub fn chromium() -> Option<PathBuf> {
    if let Ok(p) = std::env::var("MHI_CHROMIUM") {
        return Some(PathBuf::from(p));
    }
    [
        "/usr/bin/chromium",
        "/usr/bin/chromium-browser",
        "/usr/bin/google-chrome",
    ]
    .iter()
    .map(PathBuf::from)
    .find(|p| p.is_file())
}

/// Chromium, or `None` with a printed reason where there is none — a failure instead when
/// `MHI_REQUIRE_BROWSER=1` (as `.ci/run` sets after installing Debian's `chromium`).
pub fn chromium_or_skip() -> Option<PathBuf> {
    let found = chromium();
    if found.is_none() {
        assert!(
            std::env::var("MHI_REQUIRE_BROWSER").as_deref() != Ok("1"),
            "MHI_REQUIRE_BROWSER=1 but no Chromium found (install Debian's chromium)"
        );
        eprintln!(
            "SKIPPED: no Chromium at /usr/bin/chromium (or $MHI_CHROMIUM); the viewer was not checked"
        );
    }
    found
}

/// Headless Chromium with WebGL2 on the CPU and no network traffic of its own.
fn headless(browser: &Path) -> Command {
    let mut c = Command::new(browser);
    c.args([
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--use-angle=swiftshader",
        "--enable-unsafe-swiftshader",
        "--disable-background-networking",
        "--disable-component-update",
        "--disable-sync",
        "--no-first-run",
    ]);
    c
}

/// A screenshot of `page#hash`, cropped to `w × h` (the window is larger: headless Chromium's
/// viewport has a minimum size).
pub fn screenshot(
    browser: &Path,
    page: &Path,
    hash: &str,
    w: u32,
    h: u32,
    dir: &Path,
) -> image::RgbImage {
    let shot = dir.join(format!("shot-{}.png", hash.replace(['=', '&'], "_")));
    let out = headless(browser)
        .args([
            "--hide-scrollbars",
            "--force-device-scale-factor=1",
            "--window-size=480,360",
        ])
        .arg(format!("--user-data-dir={}", dir.join("profile").display()))
        .arg(format!("--screenshot={}", shot.display()))
        .arg(format!("file://{}#{hash}&nohud&zoom=1", page.display()))
        .output()
        .expect("run chromium");
    assert!(
        shot.is_file(),
        "chromium wrote no screenshot: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let img = image::open(&shot).expect("screenshot").to_rgb8();
    image::imageops::crop_imm(&img, 0, 0, w, h).to_image()
}

/// The DOM of `page#hash` after its scripts ran (Chromium's `--dump-dom`).
pub fn dump_dom(browser: &Path, page: &Path, hash: &str, dir: &Path) -> String {
    let out = headless(browser)
        .args(["--virtual-time-budget=3000", "--dump-dom"])
        .arg(format!(
            "--user-data-dir={}",
            dir.join("profile-dom").display()
        ))
        .arg(format!("file://{}#{hash}", page.display()))
        .output()
        .expect("run chromium");
    String::from_utf8_lossy(&out.stdout).into_owned()
}
