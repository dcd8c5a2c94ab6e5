//! report.html opened in headless Chromium (issue 51): the 3D view drew, the page logged nothing
//! to its console and raised no error, and a screenshot shows the view with trajectory pixels in
//! it. The screenshot stays in CI's output folder.

use std::path::Path;
use std::process::Command;

use anyhow::{Context, Result, bail};

/// Browsers tried, in order (Debian's package installs `chromium`).
const BROWSERS: [&str; 3] = ["chromium", "chromium-browser", "google-chrome"];

/// The screenshot's size, pixels: the page's title, note and 960 x 600 view.
const WINDOW: &str = "--window-size=1100,900";

/// Pixels of the trajectory's blue (`#0050ff`, within antialiasing) the screenshot must hold.
const MIN_TRAJECTORY_PIXELS: usize = 100;

/// Checks `dir/report.html`, writing its screenshot to `screenshot`.
///
/// # Errors
/// No browser; the page drew nothing, raised an error or logged to its console; the screenshot is
/// blank or shows no trajectory.
pub fn check(dir: &Path, screenshot: &Path) -> Result<()> {
    let page = std::fs::canonicalize(dir.join("report.html"))
        .with_context(|| format!("{}/report.html", dir.display()))?;
    let url = format!("file://{}", page.display());
    let browser = BROWSERS
        .iter()
        .find(|b| Command::new(b).arg("--version").output().is_ok_and(|o| o.status.success()))
        .context("no headless browser: install Debian's `chromium` (.ci/run does)")?;
    let headless =
        ["--headless", "--no-sandbox", "--disable-gpu", "--enable-logging=stderr", "--v=0"];
    let dom = Command::new(browser)
        .args(headless)
        .args(["--dump-dom", &url])
        .output()
        .with_context(|| format!("running {browser}"))?;
    let (html, log) = (String::from_utf8_lossy(&dom.stdout), String::from_utf8_lossy(&dom.stderr));
    let body = html.find("<body").map(|i| &html[i..]).and_then(|b| b.split('>').next());
    let body = body.with_context(|| format!("{browser} gave no page body for {url}"))?;
    if body.contains("data-error") {
        bail!("report.html raised a script error: {body}>");
    }
    let drawn = body
        .split("data-drawn=\"")
        .nth(1)
        .and_then(|rest| rest.split('"').next())
        .and_then(|n| n.parse::<u64>().ok());
    let Some(drawn) = drawn.filter(|&n| n > 0) else {
        bail!("report.html's 3D view drew nothing: {body}>");
    };
    if let Some(line) = log.lines().find(|l| l.contains(":CONSOLE")) {
        bail!("report.html logged to its console: {line}");
    }
    let shot = Command::new(browser)
        .args(headless)
        .args([WINDOW, &format!("--screenshot={}", screenshot.display()), &url])
        .output()
        .with_context(|| format!("running {browser}"))?;
    if !shot.status.success() {
        bail!("{browser} could not take the screenshot: {}", String::from_utf8_lossy(&shot.stderr));
    }
    let image = image::open(screenshot)
        .with_context(|| format!("reading {}", screenshot.display()))?
        .to_rgb8();
    let inked = image.pixels().filter(|p| p.0.iter().any(|&c| c < 200)).count();
    let blue = image.pixels().filter(|p| p.0[0] < 60 && p.0[1] < 140 && p.0[2] > 200).count();
    let total = image.pixels().len();
    if inked < total / 100 || blue < MIN_TRAJECTORY_PIXELS {
        bail!(
            "the screenshot {} looks blank: {inked} of {total} pixels inked, {blue} trajectory \
             pixels",
            screenshot.display()
        );
    }
    eprintln!(
        "report.html: the 3D view drew {drawn} items, no console output; screenshot {} ({blue} \
         trajectory pixels)",
        screenshot.display()
    );
    Ok(())
}
