//! The HTML report in a real browser: scan `sample_assets/` with `--html`, open the page in headless
//! Chromium with `#selftest` (the page sorts, filters, opens a detail view and checks the picture,
//! then writes PASS or FAIL into the DOM, read back through `--dump-dom`), fail on any console
//! message, and save a screenshot of a detail view to `target/tmp/report.png`.
//!
//! Skips with a message when Chromium is not installed (`apt-get install chromium`); CI installs it.

use std::fs::File;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

fn chromium() -> Option<PathBuf> {
    let path = std::env::var_os("PATH")?;
    ["chromium", "chromium-browser", "google-chrome"]
        .iter()
        .flat_map(|name| std::env::split_paths(&path).map(move |dir| dir.join(name)))
        .find(|p| p.is_file())
}

/// What a browser run printed.
struct Output {
    stdout: Vec<u8>,
    stderr: Vec<u8>,
}

/// Runs headless Chromium on `url` with `extra` flags; kills it after a minute. Its output goes to
/// files (a full pipe would block Chromium's logging while we wait).
fn browse(browser: &Path, profile: &Path, url: &str, extra: &[&str]) -> Output {
    let out = profile.with_extension("stdout");
    let err = profile.with_extension("stderr");
    let mut child = Command::new(browser)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            "--disable-default-apps",
            "--disable-extensions",
            "--no-first-run",
            "--hide-scrollbars",
            "--enable-logging=stderr",
            "--v=0",
        ])
        .arg(format!("--user-data-dir={}", profile.display()))
        .args(extra)
        .arg(url)
        .stdout(File::create(&out).unwrap())
        .stderr(File::create(&err).unwrap())
        .spawn()
        .expect("chromium starts");
    let deadline = Instant::now() + Duration::from_secs(60);
    while child
        .try_wait()
        .expect("chromium can be waited for")
        .is_none()
    {
        if Instant::now() > deadline {
            let _ = child.kill();
            panic!("chromium did not finish within a minute on {url}");
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    Output {
        stdout: std::fs::read(&out).unwrap(),
        stderr: std::fs::read(&err).unwrap(),
    }
}

/// Console messages in Chromium's log (`INFO:CONSOLE(12)] "message", source: ...`).
fn console_lines(stderr: &[u8]) -> Vec<String> {
    String::from_utf8_lossy(stderr)
        .lines()
        .filter(|l| l.contains(":CONSOLE"))
        .map(str::to_owned)
        .collect()
}

#[test]
fn the_report_of_the_sample_assets_works_in_a_browser() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let dir = tempfile::tempdir().unwrap();
    let page = dir.path().join("report.html");
    let scan = Command::new(env!("CARGO_BIN_EXE_meshvet"))
        .current_dir(root)
        .args(["scan", "sample_assets", "--quiet", "--html"])
        .arg(&page)
        .output()
        .unwrap();
    assert_eq!(
        scan.status.code(),
        Some(1),
        "the samples hold failing meshes"
    );
    let html = std::fs::read_to_string(&page).expect("the page is written");
    let lower = html.to_ascii_lowercase();
    for external in [
        "http://",
        "https://",
        "src=\"//",
        "href=\"//",
        "src='//",
        "href='//",
    ] {
        assert!(!lower.contains(external), "the page refers to {external}");
    }
    assert!(html.contains("<script type='text/x-svg' id='pic0'><svg"));
    assert!(html.len() < 2_000_000, "{} bytes for 22 meshes", html.len());

    let Some(browser) = chromium() else {
        println!("skipped the browser half: chromium is not installed (apt-get install chromium)");
        return;
    };
    let url = format!("file://{}", page.display()).replace(' ', "%20");
    let profile = dir.path().join("profile");

    let run = browse(
        &browser,
        &profile,
        &format!("{url}#selftest"),
        &["--dump-dom"],
    );
    let dom = String::from_utf8_lossy(&run.stdout);
    let verdict = dom
        .split("<div id=\"selftest\"")
        .nth(1)
        .and_then(|s| s.split("</div>").next())
        .unwrap_or("no #selftest element in the dumped DOM");
    println!("self-test: {verdict}");
    assert!(verdict.contains("SELFTEST PASS"), "{verdict}");
    let console = console_lines(&run.stderr);
    assert!(console.is_empty(), "console messages: {console:#?}");

    // A detail view with marks (two boxes sharing an edge) for the README.
    let shot = Path::new(env!("CARGO_TARGET_TMPDIR")).join("report.png");
    let _ = std::fs::remove_file(&shot);
    let run = browse(
        &browser,
        &profile,
        &format!("{url}#mesh=print%2Ftwin_boxes.stl"),
        &[
            &format!("--screenshot={}", shot.display()),
            "--window-size=1280,1000",
        ],
    );
    let console = console_lines(&run.stderr);
    assert!(console.is_empty(), "console messages: {console:#?}");
    let png = std::fs::read(&shot).expect("a screenshot");
    assert!(
        png.starts_with(b"\x89PNG") && png.len() > 20_000,
        "{} bytes",
        png.len()
    );
    println!("screenshot: {}", shot.display());
}
