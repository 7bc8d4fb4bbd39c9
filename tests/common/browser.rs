//! Pages opened in real headless Chromium (Debian `chromium`, installed by scripts/setup), with
//! WebGL on SwiftShader, Chromium's software renderer, so it runs where there is no GPU.

use std::path::{Path, PathBuf};
use std::process::Command;

/// The Chromium program, or `None` with a printed reason.
pub fn chromium() -> Option<PathBuf> {
    let found = Command::new("chromium")
        .arg("--version")
        .output()
        .is_ok_and(|o| o.status.success());
    if found {
        Some(PathBuf::from("chromium"))
    } else {
        super::skip("chromium is not installed (scripts/setup installs it)");
        None
    }
}

/// `page` opened from the file system in a `width`x`height` window, screenshot once its
/// scripts have had 20 s of (virtual) time. Images are off, so whatever colour the screenshot
/// holds was drawn by the page's scripts (its WebGL viewer), not by its `<img>`s. (A page
/// scrolled to a `#fragment` came out blank in Chromium 156's headless screenshots: make the
/// window tall enough instead.)
pub fn screenshot(page: &Path, width: u32, height: u32) -> image::RgbImage {
    let dir = tempfile::tempdir().unwrap();
    let shot = dir.path().join("shot.png");
    let url = format!("file://{}", page.canonicalize().unwrap().display());
    let out = Command::new("chromium")
        .args([
            "--headless",
            "--no-sandbox",
            "--use-angle=swiftshader",
            "--enable-unsafe-swiftshader",
            "--hide-scrollbars",
            "--blink-settings=imagesEnabled=false",
            "--virtual-time-budget=20000",
        ])
        .arg(format!(
            "--user-data-dir={}",
            dir.path().join("profile").display()
        ))
        .arg(format!("--window-size={width},{height}"))
        .arg(format!("--screenshot={}", shot.display()))
        .arg(&url)
        .output()
        .unwrap();
    assert!(
        out.status.success() && shot.is_file(),
        "chromium could not screenshot {url}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    image::open(&shot).unwrap().to_rgb8()
}
