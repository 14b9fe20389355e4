//! The HTML report in a real browser: scan `sample_assets/` with `--html`, open the page in headless
//! Chromium with `#selftest` (the page sorts, filters, opens a detail view and checks the picture,
//! then writes PASS or FAIL into the DOM, read back through `--dump-dom`), fail on any console
//! message, and save a screenshot of a detail view to `target/tmp/report.png`.
//!
//! Layout and pictures are checked by [`CHECKS`], a script the test appends to a copy of the page:
//! at 1366x768, 1440x900 and 1920x1080 the status, path and findings cells of every row lie inside
//! the viewport and the page never scrolls sideways; a long message, path or mesh name is cut by an
//! ellipsis with the whole text in its tooltip (a path's folders before its file name); the mesh
//! column is there only when some mesh has a name. In the pictures, no face is cancelled by another
//! of its path, every point inside a face of an inside-out shell hits a face (no gap where faces
//! overlap), the solid around the hollow block's cavity is see-through with the cavity under it,
//! and inconsistently wound edges are marked. Screenshots of the table go to
//! `target/tmp/table-WIDTHxHEIGHT.png`.
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
/// The browser wrote a screenshot that is a PNG of some substance; prints where it is.
fn assert_screenshot(shot: &Path) {
    let png = std::fs::read(shot).expect("a screenshot");
    assert!(
        png.starts_with(b"\x89PNG") && png.len() > 20_000,
        "{} bytes",
        png.len()
    );
    println!("screenshot: {}", shot.display());
}

fn console_lines(stderr: &[u8]) -> Vec<String> {
    String::from_utf8_lossy(stderr)
        .lines()
        .filter(|l| l.contains(":CONSOLE"))
        .map(str::to_owned)
        .collect()
}

/// Checks run inside the page (after its own script has drawn the table), configured by `EXPECT`:
/// `meshNames` (whether some row has a mesh name), `longMessage` / `longPath` / `longMesh` (report
/// paths of rows whose message / path / mesh name is longer than its cell, or absent), `pictures`
/// (run the picture checks; the page is of `sample_assets/`). Writes `LAYOUT PASS` or `LAYOUT FAIL <problems>` and a few widths
/// into `<pre id="layout-check">`. The page is scrolled back to its top when done (a headless
/// screenshot of a page its script scrolled leaves the top unpainted).
const CHECKS: &str = r##"
(function () {
  var problems = [], notes = {};
  function check(ok, what) { if (!ok) problems.push(what); }
  function rowOf(path) { return ROWS.findIndex(function (r) { return r[C.path] === path; }); }
  try {
    var width = document.documentElement.clientWidth;
    var table = document.getElementById("mesh-table");
    window.scrollTo(0, table.getBoundingClientRect().top + window.scrollY - 4);
    check(document.documentElement.scrollWidth <= width, "the page scrolls sideways: " + document.documentElement.scrollWidth + " > " + width);
    var heads = Array.from(document.querySelectorAll("#head th")).map(function (th) { return th.getAttribute("data-col"); });
    var named = ROWS.some(function (r) { return r[C.mesh] !== ""; });
    check(named === EXPECT.meshNames, "rows with a mesh name: " + named + ", expected " + EXPECT.meshNames);
    check(heads.indexOf("mesh") >= 0 === named, "mesh column shown: " + (heads.indexOf("mesh") >= 0) + " with mesh names: " + named);
    var rows = document.querySelectorAll("#rows tr");
    check(rows.length === Math.min(ROWS.length, 200) && rows.length > 5, rows.length + " rows drawn");
    rows.forEach(function (tr) {
      ["status", "path", "findings"].forEach(function (col) {
        var box = tr.children[heads.indexOf(col)].getBoundingClientRect();
        if (!(box.width > 0 && box.left >= 0 && box.right <= width + 0.5)) {
          problems.push(col + " of row " + tr.getAttribute("data-row") + " at " + box.left + ".." + box.right + ", outside 0.." + width);
        }
      });
      var high = tr.getBoundingClientRect().height;
      if (high > 40) problems.push("row " + tr.getAttribute("data-row") + " is " + high + " px high");
    });
    var first = rows[0].getBoundingClientRect();
    check(first.top >= 0 && first.bottom <= window.innerHeight, "the first row is not on screen once the table is scrolled to");
    window.scrollTo(0, 0);
    notes.path = Math.round(rows[0].children[heads.indexOf("path")].getBoundingClientRect().width);
    notes.findings = Math.round(rows[0].children[heads.indexOf("findings")].getBoundingClientRect().width);
    check(notes.findings >= 300, "the findings column is only " + notes.findings + " px wide");
    check(notes.path >= 300, "the path column is only " + notes.path + " px wide");
    function cellOf(path, col) {
      var tr = document.querySelector("#rows tr[data-row='" + rowOf(path) + "']");
      return tr && tr.children[heads.indexOf(col)];
    }
    // The width of an element's text laid out in full, and of the box that shows it (to a fraction
    // of a pixel: a name a quarter pixel too wide for its box already ends in an ellipsis).
    function textWidth(el) { var range = document.createRange(); range.selectNodeContents(el); return range.getBoundingClientRect().width; }
    function boxWidth(el) { return el.getBoundingClientRect().width; }
    function cut(el, what) {
      var style = getComputedStyle(el);
      check(style.textOverflow === "ellipsis" && style.overflowX === "hidden" && style.whiteSpace === "nowrap", what + " would not end in an ellipsis");
      check(textWidth(el) > boxWidth(el) + 1, what + " is not cut (" + textWidth(el) + " in " + boxWidth(el) + " px)");
    }
    if (EXPECT.longMessage) {
      var td = cellOf(EXPECT.longMessage, "findings"), message = ROWS[rowOf(EXPECT.longMessage)][C.message];
      check(message.length > 150, "the long message has only " + message.length + " characters");
      check(td.title === message, "the tooltip is not the whole message");
      check(td.textContent === message, "the cell does not hold the whole message");
      cut(td, "the long message");
    }
    if (EXPECT.longPath) {
      var cell = cellOf(EXPECT.longPath, "path"), file = cell.querySelector(".file"), dir = cell.querySelector(".dir");
      check(cell.title === EXPECT.longPath, "the path's tooltip is not the whole path");
      check(cell.textContent === EXPECT.longPath, "the cell does not hold the whole path");
      cut(dir, "the long path's folders");
      check(textWidth(file) <= boxWidth(file), "the file name is cut (" + textWidth(file) + " in " + boxWidth(file) + " px) although the folders could give way");
    }
    if (EXPECT.longMesh) {
      var named = cellOf(EXPECT.longMesh, "mesh"), name = ROWS[rowOf(EXPECT.longMesh)][C.mesh];
      check(name.length > 60, "the long mesh name has only " + name.length + " characters");
      check(named.title === name && named.textContent === name, "the mesh cell or its tooltip is not the whole name");
      cut(named, "the long mesh name");
    }
    if (EXPECT.pictures) {
      // Every picture: the centre of each face lies in the fill of its own path (the nonzero rule
      // cancels a face where another of its path overlaps it with the opposite turn).
      var pictures = 0, centres = 0, cancelled = [];
      ROWS.forEach(function (row, r) {
        if (row[NC + 3] < 0) return;
        openDetail(r);
        pictures++;
        var svg = document.querySelector("#picture svg"), lost = 0;
        svg.querySelectorAll("path[color]").forEach(function (p) {
          p.getAttribute("d").split("z").forEach(function (outline) {
            var n = outline.replace("M", "").trim().split(/\s+/).map(Number);
            if (n.length !== 6) return;
            var centre = svg.createSVGPoint();
            centre.x = (n[0] + n[2] + n[4]) / 3;
            centre.y = (n[1] + n[3] + n[5]) / 3;
            centres++;
            if (!p.isPointInFill(centre)) lost++;
          });
        });
        if (lost > 0) cancelled.push(row[C.path] + " " + row[C.mesh] + ": " + lost);
      });
      notes.pictures = pictures;
      notes.faceCentres = centres;
      check(pictures >= 15 && centres > 1000, "only " + pictures + " pictures, " + centres + " faces");
      check(cancelled.length === 0, "faces cancelled in " + cancelled.join(", "));
      // An inside-out shell: each face's centre, and points between it and its corners, hit a face.
      openDetail(rowOf("rules/inside-out-shell.obj"));
      var svg = document.querySelector("#picture svg"), tested = 0, gaps = 0;
      svg.querySelectorAll("path[color]").forEach(function (p) {
        var m = p.getScreenCTM();
        p.getAttribute("d").split("z").forEach(function (outline) {
          var n = outline.replace("M", "").trim().split(/\s+/).map(Number);
          if (n.length !== 6) return;
          var cx = (n[0] + n[2] + n[4]) / 3, cy = (n[1] + n[3] + n[5]) / 3;
          [[cx, cy], [0, 1], [2, 3], [4, 5]].forEach(function (k, i) {
            var x = i === 0 ? cx : cx + 0.6 * (n[k[0]] - cx), y = i === 0 ? cy : cy + 0.6 * (n[k[1]] - cy);
            var q = new DOMPoint(x, y).matrixTransform(m), hit = document.elementFromPoint(q.x, q.y);
            tested++;
            if (!(hit && hit.tagName === "path" && svg.contains(hit))) gaps++;
          });
        });
      });
      notes.insideOutPoints = tested;
      check(tested >= 32, "only " + tested + " points tested in the inside-out shell");
      check(gaps === 0, gaps + " of " + tested + " points inside faces of the inside-out shell show no face");
      // The hollow block: the cavity's centre is the middle of each view, under see-through faces.
      openDetail(rowOf("print/hollow_block.obj"));
      svg = document.querySelector("#picture svg");
      var through = document.createElement("style");
      through.textContent = ".pic .g { pointer-events: none; }";
      svg.querySelectorAll(":scope > g").forEach(function (view, i) {
        var q = new DOMPoint(120, 120).matrixTransform(view.getScreenCTM());
        var top = document.elementFromPoint(q.x, q.y);
        check(top && top.classList.contains("g") && parseFloat(getComputedStyle(top).opacity) <= 0.5, "view " + i + ": the solid over the cavity is not see-through");
        document.head.appendChild(through);
        var under = document.elementFromPoint(q.x, q.y);
        through.remove();
        var c = under && under.getAttribute("color");
        var rgb = c ? [1, 2, 3].map(function (k) { return parseInt(c[k], 16); }) : [0, 0, 0];
        check(c && !under.classList.contains("g") && rgb[0] > rgb[1] && rgb[2] > rgb[1], "view " + i + ": no inside-out (violet) cavity face under the see-through solid: " + (under && under.outerHTML.slice(0, 50)));
      });
      // Inconsistently wound edges: marked in their own colour on top, and in the legend.
      openDetail(rowOf("rules/inconsistent-winding.obj"));
      svg = document.querySelector("#picture svg");
      check(svg.querySelectorAll("path.i").length === 2 && svg.querySelectorAll("path.w").length === 2, "inconsistent edges are not marked in both views");
      var halo = svg.querySelector("path.w"), at = halo.getAttribute("d").match(/-?\d+/g).map(Number);
      var q = new DOMPoint(at[0], at[1]).matrixTransform(halo.getScreenCTM()), hit = document.elementFromPoint(q.x, q.y);
      check(hit && (hit.classList.contains("w") || hit.classList.contains("i")), "the inconsistent edge's mark is not on top: " + (hit && hit.outerHTML.slice(0, 50)));
      check(getComputedStyle(svg.querySelector("path.i")).stroke === "rgb(0, 136, 119)", "the inconsistent edges are not teal");
      check(document.querySelector(".legend").textContent.indexOf("inconsistently wound edges") >= 0, "no legend entry for inconsistent edges");
      closeDetail();
    }
  } catch (e) {
    problems.push("exception: " + e.message);
  }
  var out = document.createElement("pre");
  out.id = "layout-check";
  out.textContent = (problems.length === 0 ? "LAYOUT PASS " : "LAYOUT FAIL " + problems.join("; ") + " ") + JSON.stringify(notes);
  document.body.appendChild(out);
})();
"##;

/// A copy of `page` beside it, named `name`, with [`CHECKS`] run after the page's own script.
fn with_checks(page: &Path, name: &str, expect: &str) -> PathBuf {
    let html = std::fs::read_to_string(page).unwrap();
    let end = html.rfind("</body>").expect("the page ends its body");
    let checked = format!(
        "{}<script>var EXPECT = {expect};</script><script>{CHECKS}</script>{}",
        &html[..end],
        &html[end..]
    );
    let path = page.with_file_name(name);
    std::fs::write(&path, checked).unwrap();
    path
}

/// The verdict [`CHECKS`] wrote into the dumped DOM.
fn layout_verdict(dom: &[u8]) -> String {
    String::from_utf8_lossy(dom)
        .split("<pre id=\"layout-check\">")
        .nth(1)
        .and_then(|s| s.split("</pre>").next())
        .unwrap_or("no #layout-check element in the dumped DOM")
        .to_owned()
}

fn file_url(path: &Path) -> String {
    format!("file://{}", path.display()).replace(' ', "%20")
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

    // The table at a laptop's width, with the mesh column (some samples name their meshes), and
    // the pictures of the inside-out shell, the hollow block and the inconsistent winding.
    let checked = with_checks(&page, "checked.html", "{meshNames: true, pictures: true}");
    let run = browse(
        &browser,
        &profile,
        &file_url(&checked),
        &["--dump-dom", "--window-size=1366,768"],
    );
    let verdict = layout_verdict(&run.stdout);
    println!("checks: {verdict}");
    assert!(verdict.starts_with("LAYOUT PASS"), "{verdict}");
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
    assert_screenshot(&shot);
}

/// A tree without mesh names, holding a path too long for its cell at any width, a PLY file whose
/// broken header gives a message of about 300 characters and a glTF file whose message holds a long
/// absolute path (one word of ~110 characters): at 1366x768, 1440x900 and 1920x1080, status,
/// path and findings stay on screen, the long texts end in an ellipsis with the whole in a
/// tooltip (the path's folders give way before its file name) and there is no mesh column.
#[test]
fn the_table_fits_a_laptop_screen() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("sample_assets");
    let dir = tempfile::tempdir().unwrap();
    let tree = dir.path().join("assets");
    let long_folder = "a-library-of-assets-with-long-folder-names/characters-and-creatures-for-the-second-level/lod0-exports-from-the-modelling-tool";
    let long_path = format!("{long_folder}/spider-queen_non-manifold.obj");
    let copies = [
        ("rules/non-manifold-edge.obj", long_path.as_str()),
        ("print/hollow_block.obj", "print/hollow_block.obj"),
        ("print/twin_boxes.stl", "print/twin_boxes.stl"),
        ("print/hex_bolt_head.off", "print/hex_bolt_head.off"),
        ("rules/hole.obj", "rules/hole.obj"),
        ("rules/duplicate-face.obj", "rules/duplicate-face.obj"),
        ("rules/inside-out-shell.obj", "rules/inside-out-shell.obj"),
        (
            "rules/non-manifold-vertex.obj",
            "rules/non-manifold-vertex.obj",
        ),
        ("scans/pebble.ply", "scans/pebble.ply"),
        ("scans/vase.off", "scans/vase.off"),
    ];
    for (from, to) in copies {
        let to = tree.join(to);
        std::fs::create_dir_all(to.parent().unwrap()).unwrap();
        std::fs::copy(root.join(from), to).unwrap();
    }
    std::fs::create_dir_all(tree.join("broken")).unwrap();
    std::fs::write(
        tree.join("broken/header.ply"),
        "ply\nformat ascii 1.0\nelement vertex 3x\nend_header\n",
    )
    .unwrap();
    // Its message names the missing file twice, once as an absolute path: a long word a table
    // laid out by its content would widen the findings column for, off the screen.
    std::fs::write(
        tree.join("broken/missing-buffer.gltf"),
        r#"{"asset": {"version": "2.0"},
            "buffers": [{"uri": "exported-geometry-of-the-spider-queen-for-the-second-level-lod0-v7.bin", "byteLength": 36}],
            "bufferViews": [{"buffer": 0, "byteLength": 36}],
            "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]}],
            "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
            "nodes": [{"mesh": 0}], "scenes": [{"nodes": [0]}], "scene": 0}"#,
    )
    .unwrap();
    let page = dir.path().join("report.html");
    let scan = Command::new(env!("CARGO_BIN_EXE_meshvet"))
        .current_dir(dir.path())
        .args(["scan", "assets", "--quiet", "--html"])
        .arg(&page)
        .output()
        .unwrap();
    assert_eq!(scan.status.code(), Some(1), "{scan:?}");
    let Some(browser) = chromium() else {
        println!("skipped: chromium is not installed (apt-get install chromium)");
        return;
    };
    let expect = format!(
        "{{meshNames: false, longMessage: 'broken/header.ply', longPath: '{long_path}', pictures: false}}"
    );
    let checked = with_checks(&page, "checked.html", &expect);
    for (width, height) in [(1366, 768), (1440, 900), (1920, 1080)] {
        let size = format!("--window-size={width},{height}");
        let profile = dir.path().join(format!("profile-{width}"));
        let run = browse(
            &browser,
            &profile,
            &file_url(&checked),
            &["--dump-dom", &size],
        );
        let verdict = layout_verdict(&run.stdout);
        println!("{width}x{height}: {verdict}");
        assert!(
            verdict.starts_with("LAYOUT PASS"),
            "{width}x{height}: {verdict}"
        );
        let console = console_lines(&run.stderr);
        assert!(console.is_empty(), "console messages: {console:#?}");

        let shot =
            Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("table-{width}x{height}.png"));
        let _ = std::fs::remove_file(&shot);
        browse(
            &browser,
            &profile,
            &file_url(&checked),
            &[&format!("--screenshot={}", shot.display()), &size],
        );
        assert_screenshot(&shot);
    }
}

/// A mesh name of 96 characters without a space (as exporters write them) beside a few unnamed
/// meshes: at 1366x768 the mesh column is there, its cell is cut by an ellipsis with the whole name
/// in its tooltip, and it pushes neither the findings nor anything else off the screen (a table
/// laid out by its content widened the mesh column to the whole name).
#[test]
fn a_long_mesh_name_stays_in_its_column() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("sample_assets");
    let dir = tempfile::tempdir().unwrap();
    let tree = dir.path().join("assets");
    std::fs::create_dir_all(&tree).unwrap();
    for name in [
        "hole.obj",
        "non-manifold-edge.obj",
        "inside-out-shell.obj",
        "cavity.obj",
        "duplicate-face.obj",
        "zero-area-face.obj",
    ] {
        std::fs::copy(root.join("rules").join(name), tree.join(name)).unwrap();
    }
    let mesh = "SM_spider_queen_body_with_all_eight_legs_and_the_abdomen_LOD0_exported_from_the_modelling_tool";
    // One triangle, (0,0,0) (1,0,0) (0,1,0): nine little-endian f32, base64 of their 36 bytes.
    let gltf = format!(
        r#"{{"asset": {{"version": "2.0"}},
            "buffers": [{{"uri": "data:application/octet-stream;base64,AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAgD8AAAAA", "byteLength": 36}}],
            "bufferViews": [{{"buffer": 0, "byteLength": 36}}],
            "accessors": [{{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]}}],
            "meshes": [{{"name": "{mesh}", "primitives": [{{"attributes": {{"POSITION": 0}}}}]}}],
            "nodes": [{{"mesh": 0}}], "scenes": [{{"nodes": [0]}}], "scene": 0}}"#
    );
    std::fs::write(tree.join("named.gltf"), gltf).unwrap();
    let page = dir.path().join("report.html");
    let scan = Command::new(env!("CARGO_BIN_EXE_meshvet"))
        .current_dir(dir.path())
        .args(["scan", "assets", "--quiet", "--html"])
        .arg(&page)
        .output()
        .unwrap();
    assert_eq!(scan.status.code(), Some(1), "{scan:?}");
    let Some(browser) = chromium() else {
        println!("skipped: chromium is not installed (apt-get install chromium)");
        return;
    };
    let checked = with_checks(
        &page,
        "checked.html",
        "{meshNames: true, longMesh: 'named.gltf'}",
    );
    let run = browse(
        &browser,
        &dir.path().join("profile"),
        &file_url(&checked),
        &["--dump-dom", "--window-size=1366,768"],
    );
    let verdict = layout_verdict(&run.stdout);
    println!("1366x768: {verdict}");
    assert!(verdict.starts_with("LAYOUT PASS"), "{verdict}");
    let console = console_lines(&run.stderr);
    assert!(console.is_empty(), "console messages: {console:#?}");
}
