//! Bad scene input: every error names the file, the line and the field; nothing panics.

use std::path::Path;
use strata::scene::parse_scene;

const BASE: &str = r#"
[image]
width = 32
height = 24

[camera]
position = [0, 1, 5]
look_at = [0, 0, 0]
fov = 40

[materials.m]
type = "lambert"
albedo = [0.5, 0.5, 0.5]
"#;

/// Parse BASE + extra, expect an error; return (line, field, message).
fn fail(extra: &str) -> (usize, String, String) {
    let text = format!("{BASE}{extra}");
    match parse_scene(Path::new("bad.toml"), &text) {
        Ok(_) => panic!("expected an error for:\n{extra}"),
        Err(e) => {
            let shown = e.to_string();
            assert!(shown.starts_with("bad.toml:"), "{shown}");
            (e.line, e.field, e.message)
        }
    }
}

/// Each case (scene text after BASE, the field its error must name, a needle on the line it must
/// name) fails there; returns the messages, in order.
fn fails_at(cases: &[(&str, &str, &str)]) -> Vec<String> {
    cases
        .iter()
        .map(|&(extra, want, needle)| {
            let (line, field, msg) = fail(extra);
            assert_eq!((field.as_str(), line), (want, line_of(extra, needle)), "{extra}");
            msg
        })
        .collect()
}

fn line_of(extra: &str, needle: &str) -> usize {
    let text = format!("{BASE}{extra}");
    text.lines().position(|l| l.contains(needle)).expect("needle") + 1
}

#[test]
fn base_scene_is_valid() {
    let s = parse_scene(Path::new("ok.toml"), BASE).expect("valid");
    assert_eq!((s.width, s.height), (32, 24));
}

#[test]
fn negative_radius_names_line_and_field() {
    let extra = "[[shapes]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = -1.0\nmaterial = \"m\"\n";
    let (line, field, msg) = fail(extra);
    assert_eq!(field, "shapes[0].radius");
    assert_eq!(line, line_of(extra, "radius = -1.0"));
    assert!(msg.contains("> 0"), "{msg}");
}

/// In a file large enough to be read section by section (`scene::sections`, 1 MiB and up), errors deep
/// among the shapes still name their line and field: a negative radius and an unknown material in shape
/// 15,000 of 20,000 (found by the compiler in the sections' shifted spans), and an unknown field, a
/// wrong `shapes.transform` sub-table and a TOML syntax error (the sections decline them, and the
/// whole-document parse reports them).
#[test]
fn errors_in_large_files_name_their_line() {
    let sphere = |i: usize| format!("[[shapes]]\ntype = \"sphere\"\ncenter = [{i}, 0, 0]\nradius = 0.5\nmaterial = \"m\"\n");
    let cases = [
        ("radius = -1.0", "shapes[15000].radius"),
        ("material = \"nope\"", "shapes[15000].material"),
        ("colour = 1", "colour"),
        ("[shapes.transform]\nscale = [1, 1]", ""),
        ("radius = = 2", ""),
    ];
    for (bad, field) in cases {
        let mut extra = String::new();
        for i in 0..20_000 {
            if i == 15_000 {
                extra += "[[shapes]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\n";
                if !bad.starts_with("material") {
                    extra += "material = \"m\"\n";
                }
                if !bad.starts_with("radius") {
                    extra += "radius = 0.5\n";
                }
                extra += &format!("{bad}\n");
            } else {
                extra += &sphere(i);
            }
        }
        assert!(extra.len() > 1 << 20);
        // Errors of the scene's meaning (not of its TOML) come from the sections' own spans.
        let sections = strata::scene::sections::sectioned(&format!("{BASE}{extra}")).is_some();
        assert_eq!(sections, !field.is_empty() && field != "colour", "{bad}");
        let (line, got, msg) = fail(&extra);
        let needle = bad.lines().last().unwrap();
        assert_eq!(line, line_of(&extra, needle), "{bad}: {got}: {msg}");
        if !field.is_empty() {
            assert!(got.starts_with(field), "{bad}: field {got}, message {msg}");
        }
    }
}

#[test]
fn unknown_material_is_named() {
    let extra = "[[shapes]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 1.0\nmaterial = \"nope\"\n";
    let (line, field, msg) = fail(extra);
    assert_eq!(field, "shapes[0].material");
    assert_eq!(line, line_of(extra, "\"nope\""));
    assert!(msg.contains("nope") && msg.contains("defined: m"), "{msg}");
}

#[test]
fn unknown_field_is_rejected_with_its_line() {
    let extra = "[[shapes]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 1.0\nmaterial = \"m\"\ncolour = 3\n";
    let (line, field, msg) = fail(extra);
    assert_eq!(field, "colour");
    assert_eq!(line, line_of(extra, "colour"));
    assert!(msg.contains("unknown field"), "{msg}");
}

#[test]
fn wrong_type_is_rejected_with_its_line() {
    let extra = "[[shapes]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = \"big\"\nmaterial = \"m\"\n";
    let (line, _, msg) = fail(extra);
    assert_eq!(line, line_of(extra, "\"big\""));
    assert!(msg.contains("invalid type") || msg.contains("expected"), "{msg}");
}

#[test]
fn missing_field_is_named() {
    let extra = "[[shapes]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nmaterial = \"m\"\n";
    let (_, field, msg) = fail(extra);
    assert_eq!(field, "shapes[0].radius");
    assert!(msg.contains("missing"), "{msg}");
}

#[test]
fn camera_errors() {
    let bad = BASE.replace("look_at = [0, 0, 0]", "look_at = [0, 1, 5]");
    let e = parse_scene(Path::new("c.toml"), &bad).unwrap_err();
    assert_eq!(e.field, "camera.look_at");
    assert_eq!(e.line, bad.lines().position(|l| l.starts_with("look_at")).unwrap() + 1);
    let bad = BASE.replace("fov = 40", "fov = 40\nup = [0, 0, 0]");
    assert_eq!(parse_scene(Path::new("c.toml"), &bad).unwrap_err().field, "camera.up");
    let bad = BASE.replace("fov = 40", "fov = 40\nup = [0, -1, -5]");
    assert_eq!(parse_scene(Path::new("c.toml"), &bad).unwrap_err().field, "camera.up");
    let bad = BASE.replace("fov = 40", "fov = 180");
    assert_eq!(parse_scene(Path::new("c.toml"), &bad).unwrap_err().field, "camera.fov");
    // Looking straight down without an `up`: the view is named, not the `up` the file does not have.
    let bad = BASE.replace("look_at = [0, 0, 0]", "look_at = [0, -3, 5]");
    let e = parse_scene(Path::new("c.toml"), &bad).unwrap_err();
    assert_eq!((e.field.as_str(), e.line), ("camera.look_at", bad.lines().position(|l| l.starts_with("look_at")).unwrap() + 1));
    assert!(e.message.contains("give camera.up"), "{}", e.message);
    let bad = BASE.replace("fov = 40", "fov = nan");
    assert_eq!(parse_scene(Path::new("c.toml"), &bad).unwrap_err().field, "camera.fov");
    // Points that differ, far beyond the kernels' range: said as such, not as equal points.
    let bad = BASE.replace("position = [0, 1, 5]", "position = [0, 1, 1e20]").replace("look_at = [0, 0, 0]", "look_at = [0, 0, -1e20]");
    let e = parse_scene(Path::new("c.toml"), &bad).unwrap_err();
    assert!(e.field == "camera.position" && e.message.contains("1e15"), "{}", e.message);
    // A shutter time beyond f32's range is said as such, not as an unordered shutter.
    for (shutter, says) in [("[0.0, 1e39]", "beyond f32's range"), ("[1.0, 0.5]", "open <= close")] {
        let bad = BASE.replace("fov = 40", &format!("fov = 40\nshutter = {shutter}"));
        let e = parse_scene(Path::new("c.toml"), &bad).unwrap_err();
        assert!(e.field == "camera.shutter" && e.message.contains(says), "{shutter}: {}", e.message);
    }
    // An aperture is a length like any other (a trial's 1e30 rendered black); past where its lens points
    // round to a quarter of a pixel at the focus distance (here 1e6: 0.79 of a pixel), a warning.
    let with = |a: &str| BASE.replace("fov = 40", &format!("fov = 40\naperture = {a}"));
    let e = parse_scene(Path::new("c.toml"), &with("1e30")).unwrap_err();
    assert!(e.field == "camera.aperture" && e.message.contains("1e15"), "{}", e.message);
    for (a, warned) in [("1e6", true), ("1e4", false), ("0.1", false)] {
        let s = parse_scene(Path::new("c.toml"), &with(a)).unwrap();
        let said = s.warnings.iter().any(|w| w.contains("camera.aperture") && w.contains("of a pixel at the focus distance"));
        assert_eq!(said, warned, "aperture {a}: {:?}", s.warnings);
    }
}

#[test]
fn image_limits_are_errors() {
    let bad = BASE.replace("width = 32", "width = 0");
    assert_eq!(parse_scene(Path::new("i.toml"), &bad).unwrap_err().field, "image.width");
    let bad = BASE.replace("width = 32", "width = 100000000");
    assert_eq!(parse_scene(Path::new("i.toml"), &bad).unwrap_err().field, "image.width");
}

#[test]
fn field_that_does_not_apply_is_rejected() {
    let extra = "[[shapes]]\ntype = \"box\"\nmin = [0, 0, 0]\nmax = [1, 1, 1]\nradius = 2\nmaterial = \"m\"\n";
    let (line, field, _) = fail(extra);
    assert_eq!(field, "shapes[0].radius");
    assert_eq!(line, line_of(extra, "radius = 2"));
}

#[test]
fn degenerate_geometry_is_rejected() {
    let (_, field, _) = fail("[[shapes]]\ntype = \"box\"\nmin = [0, 0, 0]\nmax = [1, 0, 1]\nmaterial = \"m\"\n");
    assert_eq!(field, "shapes[0].max");
    let (_, field, _) = fail("[[shapes]]\ntype = \"quad\"\norigin = [0, 0, 0]\nu = [1, 0, 0]\nv = [2, 0, 0]\nmaterial = \"m\"\n");
    assert_eq!(field, "shapes[0].v");
    let (_, field, _) = fail("[[shapes]]\ntype = \"plane\"\npoint = [0, 0, 0]\nnormal = [0, 0, 0]\nmaterial = \"m\"\n");
    assert_eq!(field, "shapes[0].normal");
    let (_, field, _) = fail("[[lights]]\ntype = \"point\"\nposition = [0, 0, 0]\nintensity = [-1, 0, 0]\n");
    assert_eq!(field, "lights[0].intensity");
}

#[test]
fn material_errors() {
    let (_, field, _) = fail("[materials.x]\ntype = \"lambert\"\nalbedo = [1.5, 0, 0]\n");
    assert_eq!(field, "materials.x.albedo");
    let (_, field, _) = fail("[materials.x]\ntype = \"plastic\"\n");
    assert_eq!(field, "materials.x.type");
    let (_, field, _) = fail("[materials.x]\ntype = \"dielectric\"\nior = 0.5\n");
    assert_eq!(field, "materials.x.ior");
    let (_, field, _) = fail("[materials.x]\ntype = \"mirror\"\nroughness = 0.5\n");
    assert_eq!(field, "materials.x.roughness");
}

#[test]
fn csg_reference_cycles_and_depth_are_errors() {
    let cyc = "[solids.a]\nuse = \"b\"\n[solids.b]\nuse = \"a\"\n[[shapes]]\nuse = \"a\"\nmaterial = \"m\"\n";
    let (_, field, msg) = fail(cyc);
    assert!(field.ends_with(".use"), "{field}");
    assert!(msg.contains("cycle"), "{msg}");
    // 70 nested unions.
    let mut s = String::from("{ type = \"sphere\", center = [0, 0, 0], radius = 1 }");
    for _ in 0..70 {
        s = format!("{{ type = \"csg\", op = \"union\", children = [{s}] }}");
    }
    let deep = format!("[[shapes]]\ntype = \"csg\"\nop = \"union\"\nmaterial = \"m\"\nchildren = [{s}]\n");
    let (_, _, msg) = fail(&deep);
    assert!(msg.contains("deeper") || msg.contains("depth") || msg.contains("recursion"), "{msg}");
}

/// A half-space left unbounded (a union operand, or the solid a difference subtracts from) is an error
/// that says where a half-space may go; intersected with a bounded solid, or subtracted, it is fine.
#[test]
fn an_unbounded_half_space_says_where_one_belongs() {
    let hs = "{ type = \"halfspace\", point = [0, 0, 0], normal = [0, 1, 0] }";
    let ball = "{ type = \"sphere\", center = [0, 0, 0], radius = 1 }";
    let solid =
        |op: &str, a: &str, b: &str| format!("[[shapes]]\ntype = \"csg\"\nop = \"{op}\"\nmaterial = \"m\"\nchildren = [{a}, {b}]\n");
    // The error names the child that makes the solid unbounded, at its own line, however deep.
    let nested = |op: &str, a: &str, b: &str| format!("{{ type = \"csg\", op = \"{op}\", children = [{a}, {b}] }}");
    let hs2 = "{ type = \"halfspace\", point = [0, 0, 0], normal = [0, -1, 0] }";
    for (op, a, b, culprit) in [
        ("difference", hs, ball, "shapes[0].children[0]"),
        ("union", ball, hs, "shapes[0].children[1]"),
        ("union", ball, &nested("difference", hs, ball), "shapes[0].children[1].children[0]"),
        ("difference", &nested("union", ball, hs), ball, "shapes[0].children[0].children[1]"),
        ("union", ball, &nested("intersection", hs, hs2), "shapes[0].children[1]"),
    ] {
        let (_, field, msg) = fail(&solid(op, a, b));
        assert_eq!(field, culprit, "{msg}");
        assert!(msg.contains("unbounded") && msg.contains("intersected with a bounded solid or subtracted from one"), "{msg}");
        assert!(msg.contains("`shapes[0]`"), "the message names the solid too: {msg}");
    }
    // Through a named solid: the half-space's own definition, at its line.
    let text = format!(
        "{BASE}[solids.h]\ntype = \"halfspace\"\npoint = [0, 0, 0]\nnormal = [0, 1, 0]\n{}",
        solid("union", ball, "{ use = \"h\" }")
    );
    let e = parse_scene(Path::new("bad.toml"), &text).unwrap_err();
    assert_eq!((e.field.as_str(), e.line), ("solids.h", text.lines().position(|l| l == "[solids.h]").unwrap() + 1), "{e}");
    // An unbounded union inside an intersection with a bounded solid is bounded, and accepted.
    for (op, a, b) in [("difference", ball, hs), ("intersection", hs, ball), ("intersection", ball, &nested("union", ball, hs))] {
        let text = format!("{BASE}{}", solid(op, a, b));
        parse_scene(Path::new("ok.toml"), &text).unwrap_or_else(|e| panic!("{op}: {e}"));
    }
}

#[test]
fn syntax_error_has_line() {
    let text = format!("{BASE}\n[[shapes]\n");
    let e = parse_scene(Path::new("s.toml"), &text).unwrap_err();
    assert_eq!(e.line, text.lines().count());
    // A byte-order mark opening the file is no column: errors on line 1 (at its start, after a word)
    // and later are placed as without it (a user trial saw column 2 for 1).
    for text in ["[image\n", "nonsense\n", "[image]\nwidth = \"x\"\n"] {
        let at = |t: String| parse_scene(Path::new("b.toml"), &t).map(|_| ()).unwrap_err();
        let (plain, marked) = (at(text.to_string()), at(format!("\u{feff}{text}")));
        assert_eq!((marked.line, marked.column), (plain.line, plain.column), "{text:?}: {marked}");
    }
}

/// A background the film cannot hold (every escaping camera ray makes a sample at or beyond 2^31, which
/// the film discards) is an input error naming its field and line; just below the limit is accepted,
/// and so are emitters above it (a tiny light needs a huge radiance; a render that loses samples to
/// one says so: `tests/cli.rs`).
#[test]
fn background_beyond_the_film_range_is_an_error() {
    let background = |r: &str| BASE.replace("height = 24\n", &format!("height = 24\nbackground = [0, 0, {r}]\n"));
    for big in ["2147483648", "1e30", "3.4e38"] {
        let text = background(big);
        let e = parse_scene(Path::new("bad.toml"), &text).expect_err("a background beyond the film's range");
        assert_eq!(e.field, "image.background");
        assert_eq!(e.line, text.lines().position(|l| l.contains("background")).unwrap() + 1);
        assert!(e.message.contains("film's range"), "{}", e.message);
    }
    // The largest f32 below 2^31.
    parse_scene(Path::new("ok.toml"), &background("2147483520")).expect("a background just below 2^31");
    let light = "[[lights]]\ntype = \"quad\"\norigin = [0, 3, 0]\nu = [1e-5, 0, 0]\nv = [0, 0, 1e-5]\nradiance = [1e10, 1e10, 1e10]\n";
    parse_scene(Path::new("ok.toml"), &format!("{BASE}{light}")).expect("a tiny, bright area light");
}

/// `motion` on a top-level `use` moves the placed solid (as on any other top-level shape); on a `use`
/// inside a CSG tree it is an error naming the child's field.
#[test]
fn motion_of_a_placed_solid() {
    let solid = "[solids.peg]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 0.5\nmaterial = \"m\"\n";
    let top = format!("{solid}[[shapes]]\nuse = \"peg\"\nmotion = [0.25, 0, 0]\n");
    let s = parse_scene(Path::new("ok.toml"), &format!("{BASE}{top}")).expect("a top-level use may move");
    assert_eq!(s.prims.len(), 1);
    assert_eq!(s.prims[0].motion, glam::Vec3::new(0.25, 0.0, 0.0));
    assert!(s.features.csg, "{:?}", s.features);
    let child = format!("{solid}[[shapes]]\ntype = \"csg\"\nop = \"union\"\nchildren = [{{ use = \"peg\", motion = [1, 0, 0] }}]\n");
    let (line, field, msg) = fail(&child);
    assert_eq!(field, "shapes[0].children[0].motion");
    assert_eq!(line, line_of(&child, "children = "));
    assert!(msg.contains("top-level"), "{msg}");
}

/// A named solid is marked a hole where a group uses it (`{ use = "b", hole = true }`), which cuts it
/// out exactly as the same solid written inline with `hole = true` does (equal CSG solids, so equal
/// renders); `hole` on the definition itself is an error that says where it belongs, used or not.
#[test]
fn holes_of_named_solids_are_marked_where_they_are_used() {
    let shape = |child: &str| {
        format!("[[shapes]]\ntype = \"group\"\nmaterial = \"m\"\nchildren = [ {{ type = \"box\", min = [-1, -1, -1], max = [1, 1, 1] }}, {child} ]\n")
    };
    let ball = "[solids.b]\ntype = \"sphere\"\ncenter = [0, 0.5, 0]\nradius = 0.8\n";
    let used = parse_scene(Path::new("ok.toml"), &format!("{BASE}{ball}{}", shape("{ use = \"b\", hole = true }"))).expect("a hole by use");
    let inline = parse_scene(
        Path::new("ok.toml"),
        &format!("{BASE}{}", shape("{ type = \"sphere\", center = [0, 0.5, 0], radius = 0.8, hole = true }")),
    )
    .expect("an inline hole");
    let added = parse_scene(Path::new("ok.toml"), &format!("{BASE}{ball}{}", shape("{ use = \"b\" }"))).expect("a union");
    let dump = |s: &strata::scene::Scene| format!("{:?}", s.csg);
    assert_eq!(dump(&used), dump(&inline), "the used hole and the inline hole differ");
    assert_ne!(dump(&used), dump(&added), "the hole was added, not cut");

    let marked = "[solids.b]\ntype = \"sphere\"\ncenter = [0, 0.5, 0]\nradius = 0.8\nhole = true\n";
    for extra in [format!("{marked}{}", shape("{ use = \"b\" }")), marked.to_string()] {
        let (line, field, msg) = fail(&extra);
        assert_eq!((field.as_str(), line), ("solids.b.hole", line_of(&extra, "hole = true")));
        assert!(msg.contains("use = \"b\", hole = true"), "{msg}");
    }
}

/// Named solids no shape uses are checked as a use would check them: a bad radius, a missing
/// material name, a reference to no solid, an open shape, and (placed on its own: a user trial found
/// these silent unused) two glasses that meet, a reach past 1e15, each with
/// the error a `[[shapes]]` use gives (at the same line, or for the reach, at the use, whose transform
/// places it); a missing material alone is not an error (a
/// use may give one), nor does a leaf without one count as a glass.
#[test]
fn unused_named_solids_are_checked_too() {
    let glass2 = "[materials.g]\ntype = \"dielectric\"\nior = 1.5\n[materials.h]\ntype = \"dielectric\"\nior = 1.33\n";
    let cases = [
        ("[solids.u]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = -1\nmaterial = \"m\"\n", "solids.u.radius", "radius = -1"),
        ("[solids.u]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 1\nmaterial = \"nope\"\n", "solids.u.material", "\"nope\""),
        ("[solids.u]\nuse = \"ghost\"\n", "solids.u.use", "ghost"),
        ("[solids.u]\ntype = \"quad\"\norigin = [0, 0, 0]\nu = [1, 0, 0]\nv = [0, 1, 0]\nmaterial = \"m\"\n", "solids.u.type", "quad"),
    ];
    fails_at(&cases);
    // Unbounded is no error unused (it is a fine operand of an intersection: a named half-space is meant
    // for that), but it is where it is placed on its own.
    let unbounded = "[solids.u]\ntype = \"csg\"\nop = \"union\"\nmaterial = \"m\"\nchildren = [\n{ type = \"halfspace\", point = [0, 0, 0], normal = [0, 1, 0] },\n{ type = \"sphere\", center = [0, 1, 0], radius = 1 }]\n";
    parse_scene(Path::new("ok.toml"), &format!("{BASE}{unbounded}")).expect("an unused unbounded solid");
    let used = format!("{unbounded}[[shapes]]\nuse = \"u\"\n");
    let (line, got, msg) = fail(&used);
    assert_eq!((got.as_str(), line), ("solids.u.children[0]", line_of(&used, "halfspace")), "{msg}");
    assert!(msg.contains("unbounded"), "{msg}");
    let cut = "[solids.cut]\ntype = \"halfspace\"\npoint = [0, 0, 0]\nnormal = [0, 1, 0]\n";
    parse_scene(Path::new("ok.toml"), &format!("{BASE}{cut}")).expect("an unused named half-space");
    let placed = [
        (
            format!("{glass2}[solids.u]\ntype = \"csg\"\nop = \"union\"\nchildren = [\n{{ type = \"sphere\", center = [0, 1, 0], radius = 1, material = \"g\" }},\n{{ type = \"sphere\", center = [0.5, 1, 0], radius = 0.6, material = \"h\" }}]\n"),
            ("solids.u.children[1].material", "\"h\""),
            ("solids.u.children[1].material", "\"h\""),
            "joins the glasses `g`",
        ),
        (
            "[solids.u]\ntype = \"sphere\"\ncenter = [9e14, 1, 0]\nradius = 2e14\nmaterial = \"m\"\n".to_string(),
            ("solids.u", "[solids.u]"),
            ("shapes[0]", "[[shapes]]"),
            "1e15",
        ),
    ];
    for (def, (field, needle), (used_field, used_needle), says) in &placed {
        let (line, got, msg) = fail(def);
        assert_eq!((got.as_str(), line), (*field, line_of(def, needle)), "{msg}");
        assert!(msg.contains(says) && msg.contains("no shape uses `solids.u`"), "{msg}");
        // Used, the same error at the same place.
        let used = format!("{def}[[shapes]]\nuse = \"u\"\n");
        let (line, got, msg) = fail(&used);
        assert_eq!((got.as_str(), line), (*used_field, line_of(&used, used_needle)), "{msg}");
        assert!(msg.contains(says), "{msg}");
    }
    let no_material = "[solids.u]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 1\n";
    parse_scene(Path::new("ok.toml"), &format!("{BASE}{no_material}")).expect("a solid that takes its material where it is used");
    let one_glass = format!(
        "{glass2}[solids.u]\ntype = \"csg\"\nop = \"union\"\nchildren = [{{ type = \"sphere\", center = [0, 1, 0], radius = 1 }}, \
         {{ type = \"sphere\", center = [0.5, 1, 0], radius = 0.6, material = \"h\" }}]\n"
    );
    parse_scene(Path::new("ok.toml"), &format!("{BASE}{one_glass}")).expect("a leaf without a material is not a glass");
}

/// `children` on a shape that takes none is refused even when the list is empty; absorption on a
/// thin sheet (which has no thickness to absorb along) is refused rather than ignored.
#[test]
fn fields_that_would_be_ignored_are_errors() {
    let extra = "[[shapes]]\ntype = \"box\"\nmin = [0, 0, 0]\nmax = [1, 1, 1]\nmaterial = \"m\"\nchildren = []\n";
    let (line, field, _) = fail(extra);
    assert_eq!((field.as_str(), line), ("shapes[0].children", line_of(extra, "children")));
    for (key, value) in [("absorption", "[1, 1, 1]"), ("transmittance", "[0.5, 0.5, 0.5]")] {
        let extra = format!("[materials.g]\ntype = \"dielectric\"\nior = 1.5\nthin = true\n{key} = {value}\n");
        let (line, field, msg) = fail(&extra);
        assert_eq!((field.as_str(), line), (format!("materials.g.{key}").as_str(), line_of(&extra, key)));
        assert!(msg.contains("thin"), "{msg}");
    }
}

/// Coordinates and lengths beyond 1e15, given or reached through a transform, are errors (the sphere
/// kernel's squares overflow a little beyond: a ground sphere of radius 1e16 loses hits), not a
/// silently wrong image.
#[test]
fn magnitudes_beyond_the_kernels_range_are_errors() {
    let cases = [
        ("[[shapes]]\ntype = \"sphere\"\ncenter = [0, -1e16, 0]\nradius = 1\nmaterial = \"m\"\n", "shapes[0].center", "center"),
        ("[[shapes]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 2e15\nmaterial = \"m\"\n", "shapes[0].radius", "radius"),
        ("[[shapes]]\ntype = \"sphere\"\ncenter = [0, -8e14, 0]\nradius = 8e14\nmaterial = \"m\"\n", "shapes[0]", "[[shapes]]"),
        (
            "[[shapes]]\ntype = \"box\"\nmin = [0, 0, 0]\nmax = [1e4, 1, 1]\nmaterial = \"m\"\ntransform = { scale = [1e12, 1, 1] }\n",
            "shapes[0]",
            "[[shapes]]",
        ),
        (
            "[[shapes]]\ntype = \"plane\"\npoint = [0, 6e14, 0]\nnormal = [0, 1, 0]\nmaterial = \"m\"\ntransform = { scale = [2, 2, 2] }\n",
            "shapes[0]",
            "[[shapes]]",
        ),
    ];
    for msg in fails_at(&cases) {
        assert!(msg.contains("1e15"), "{msg}");
    }
    let big = "[[shapes]]\ntype = \"sphere\"\ncenter = [0, -4e14, 0]\nradius = 4e14\nmaterial = \"m\"\n";
    parse_scene(Path::new("ok.toml"), &format!("{BASE}{big}")).expect("a ground sphere of radius 4e14");
}

/// An empty CSG solid (an intersection of solids that do not overlap) is valid but left out, with a
/// warning that names its file, line and field; a scene without one has no warning.
#[test]
fn an_empty_csg_solid_is_left_out_with_a_warning() {
    let extra = "[[shapes]]\ntype = \"sphere\"\ncenter = [3, 0, 0]\nradius = 1\nmaterial = \"m\"\n\
                 [[shapes]]\ntype = \"csg\"\nop = \"intersection\"\nmaterial = \"m\"\n\
                 children = [ { type = \"sphere\", center = [-2, 0, 0], radius = 1 }, { type = \"sphere\", center = [2, 0, 0], radius = 1 } ]\n";
    let s = parse_scene(Path::new("e.toml"), &format!("{BASE}{extra}")).unwrap();
    assert_eq!(s.prims.len(), 1, "the empty solid is left out");
    assert_eq!(s.warnings.len(), 1, "{:?}", s.warnings);
    let w = &s.warnings[0];
    // (At the solid's `[[shapes]]` line, the one before its `type`.)
    let at = format!("e.toml:{}:", line_of(extra, "type = \"csg\"") - 1);
    assert!(w.starts_with(&at) && w.contains("`shapes[1]`") && w.contains("empty"), "{w} (expected at {at})");
    let overlapping = extra.replace("center = [2, 0, 0]", "center = [-1, 0, 0]");
    let s = parse_scene(Path::new("e.toml"), &format!("{BASE}{overlapping}")).unwrap();
    assert_eq!((s.prims.len(), s.warnings.len()), (2, 0), "{:?}", s.warnings);
}

/// A CSG solid whose bounds are not empty but whose volume is (a part drilled by a hole larger than
/// itself, `A - A`) is kept with a warning at its line; a drilled part, a thin shell and a plate of
/// touching holes get none.
#[test]
fn a_csg_solid_emptied_by_its_hole_is_warned_about() {
    let solid = |children: &str| format!("[[shapes]]\ntype = \"csg\"\nop = \"difference\"\nmaterial = \"m\"\nchildren = [ {children} ]\n");
    let cases = [
        ("{ type = \"sphere\", center = [0, 0, 0], radius = 1 }, { type = \"sphere\", center = [0, 0, 0], radius = 1.5 }", true),
        ("{ type = \"box\", min = [-1, -1, -1], max = [1, 1, 1] }, { type = \"box\", min = [-1, -1, -1], max = [1, 1, 1] }", true),
        ("{ type = \"box\", min = [0, 0, 0], max = [1e-5, 2e-5, 1e-5] }, { type = \"cylinder\", center = [0, 0, 0], radius = 1e-4, height = 1 }", true),
        ("{ type = \"sphere\", center = [0, 0, 0], radius = 1 }, { type = \"sphere\", center = [0, 0, 0], radius = 0.5 }", false),
        ("{ type = \"sphere\", center = [0, 0, 0], radius = 1 }, { type = \"sphere\", center = [0, 0, 0], radius = 0.995 }", false),
        ("{ type = \"box\", min = [-1, -1, -1], max = [1, 1, 1] }, { type = \"cylinder\", center = [0, 0, 0], radius = 0.5, height = 4 }", false),
    ];
    // A plate of 24 x 24 touching holes (radius half the pitch): pillars of material remain between
    // them. Probed at cell centres, every ray passed through hole centres or along rows of holes, and
    // the plate was warned of as empty (a user trial).
    let plate: String = std::iter::once("{ type = \"box\", min = [-1.2, 0, -1.2], max = [1.2, 0.1, 1.2] }".to_string())
        .chain((0..576).map(|k| {
            let (x, z) = (-1.15 + 0.1 * (k % 24) as f32, -1.15 + 0.1 * (k / 24) as f32);
            format!("{{ type = \"cylinder\", center = [{x}, 0.05, {z}], radius = 0.05, height = 0.1 }}")
        }))
        .collect::<Vec<_>>()
        .join(", ");
    let cases: Vec<(&str, bool)> = cases.into_iter().chain([(plate.as_str(), false)]).collect();
    for (children, empty) in cases {
        let extra = solid(children);
        let s = parse_scene(Path::new("e.toml"), &format!("{BASE}{extra}")).unwrap();
        assert_eq!(s.prims.len(), 1, "kept either way: {children}");
        if empty {
            assert_eq!(s.warnings.len(), 1, "{children}: {:?}", s.warnings);
            let at = format!("e.toml:{}:", line_of(&extra, "type = \"csg\"") - 1);
            let w = &s.warnings[0];
            assert!(w.starts_with(&at) && w.contains("`shapes[0]`") && w.contains("looks empty"), "{w} (expected at {at})");
        } else {
            assert!(s.warnings.is_empty(), "{children}: {:?}", s.warnings);
        }
    }
    // A box with walls 0.005 thick, open on top: kept unwarned at the origin; at x = 1000 its walls are
    // thinner than the tolerance (1e-2) and merge away where rays cross them squarely, but show to the
    // oblique probe rays (and to oblique camera rays): not empty, a thin part, warned of with the
    // tolerance its rays can use (before the probe's rays were turned, axis-parallel rays lost every
    // wall and it was said to look empty).
    for (x, warned) in [(0.0, false), (1000.0, true)] {
        let extra = solid(&format!(
            "{{ type = \"box\", min = [{}, -1, -1], max = [{}, 1, 1] }}, {{ type = \"box\", min = [{}, -0.995, -0.995], max = [{}, 1.5, 0.995] }}",
            x - 1.0,
            x + 1.0,
            x - 0.995,
            x + 0.995
        ));
        let s = parse_scene(Path::new("e.toml"), &format!("{BASE}{extra}")).unwrap();
        assert_eq!(s.warnings.len(), usize::from(warned), "x = {x}: {:?}", s.warnings);
        if warned {
            assert!(
                s.warnings[0].contains("has a part only 5.00e-3 thick")
                    && s.warnings[0].contains("(1.00e-2: 1e-5 of its farthest coordinate, 1.00e3, plus its bounds' diagonal"),
                "{:?}",
                s.warnings
            );
        }
    }
}

/// An intersection of two boxes that share only a face (no volume; it renders as nothing) is warned of
/// at every scale from 1e-5 to 1e5, as empty (left out) or looking empty (kept): a trial found no word
/// at 1e-5, 0.1 and 1e4, where rays lying in the shared face found it inside by the rounding of the
/// faces. Boxes that overlap by a tenth of their size are not warned of at any scale.
///
/// Turned (the solid's `rotate`: 30, 45, 60 and 90 degrees about z, 17.3 about z, 30 about y then x), at
/// scales 1e-3, 1 and 1e3: a trial's two unit boxes sharing a face, both turned 30 degrees about z, had
/// the shared face on the exact diagonal of their bounds, where the probe's axis-parallel rays lay in it
/// and found it inside by rounding: no warning (45 and 90 degrees warned).
#[test]
fn a_face_sharing_intersection_is_warned_of_at_every_scale() {
    let turns = ["0, 0, 0", "0, 0, 30", "0, 0, 45", "0, 0, 60", "0, 0, 90", "0, 0, 17.3", "30, 30, 0"];
    let all = [1e-5, 1e-4, 1e-3, 1e-2, 0.1, 1.0, 10.0, 100.0, 1e3, 1e4, 1e5];
    let cases = all.iter().map(|&x| (x, turns[0])).chain(turns[1..].iter().flat_map(|&t| [1e-3, 1.0, 1e3].map(|x| (x, t))));
    for (scale, turn) in cases {
        for (b_min, empty) in [(0.5, true), (0.4, false)] {
            let v = |x: f64| x * scale;
            let extra = format!(
                "[[shapes]]\ntype = \"csg\"\nop = \"intersection\"\nmaterial = \"m\"\ntransform = {{ rotate = [{turn}] }}\nchildren = [ \
                 {{ type = \"box\", min = [{}, {}, {}], max = [{}, {}, {}] }}, {{ type = \"box\", min = [{}, {}, {}], max = [{}, {}, {}] }} ]\n",
                v(-0.5), v(-0.5), v(-0.5), v(0.5), v(0.5), v(0.5), v(b_min), v(-0.5), v(-0.5), v(1.5), v(0.5), v(0.5)
            );
            let s = parse_scene(Path::new("f.toml"), &format!("{BASE}{extra}")).unwrap();
            let said = s.warnings.iter().any(|w| w.contains("this CSG solid is empty") || w.contains("this CSG solid looks empty"));
            assert_eq!(said, empty, "scale {scale}, turned [{turn}], second box from {b_min}: {:?}", s.warnings);
        }
    }
    // The trial's scene: unit boxes from the origin, sharing the face y = 1, each turned 30 degrees.
    let extra = "[[shapes]]\ntype = \"csg\"\nop = \"intersection\"\nmaterial = \"m\"\nchildren = [ \
                 { type = \"box\", min = [0, 0, 0], max = [1, 1, 1], transform = { rotate = [0, 0, 30] } }, \
                 { type = \"box\", min = [0, 1, 0], max = [1, 2, 1], transform = { rotate = [0, 0, 30] } } ]\n";
    let s = parse_scene(Path::new("f.toml"), &format!("{BASE}{extra}")).unwrap();
    assert!(s.warnings.iter().any(|w| w.contains("this CSG solid looks empty")), "{:?}", s.warnings);
}

/// Nesting beyond the TOML reader's own limit (about 80 levels of `[[shapes.children...]]` headers) is
/// reported at the deepest header with what it means, not as `image` at line 1; an array of tables where
/// a table belongs says so, not in serde's words.
#[test]
fn reader_limits_and_arrays_of_tables_are_explained() {
    let mut extra = String::new();
    for d in 0..90 {
        let h = format!("shapes{}", ".children".repeat(d));
        extra += &format!("[[{h}]]\ntype = \"csg\"\nop = \"union\"\n{}", if d == 0 { "material = \"m\"\n" } else { "" });
        extra += &format!("[[{h}.children]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 0.2\n");
    }
    let (line, _, msg) = fail(&extra);
    assert!(msg.contains("recursion limit") && msg.contains("64 levels"), "{msg}");
    let deepest = format!("[[shapes{}]]", ".children".repeat(90));
    assert_eq!(line, line_of(&extra, &deepest), "{msg}");
    for (extra, want) in [
        ("[[materials.glass]]\ntype = \"lambert\"\nalbedo = [0.5, 0.5, 0.5]\n", "materials.glass"),
        ("[[materials.glass]]\ntype = \"lambert\"\n[[materials.glass]]\ntype = \"lambert\"\n", "materials.glass"),
    ] {
        let (line, field, msg) = fail(extra);
        assert!(msg.contains("a single table belongs here") && !msg.contains("struct"), "{msg}");
        assert_eq!((line, field.as_str()), (line_of(extra, "[[materials.glass]]"), want), "{msg}");
    }
}

/// One leaf far from the rest widens a CSG solid's coincidence tolerance (1e-5 of its farthest
/// coordinate) for all of its leaves: a union of a notched block at the origin and a small sphere at 1e6
/// lost most of the block's notch in a user trial. Warned at the solid's line when a leaf is thinner than
/// 10 tolerances; the same solid with the sphere near is not.
#[test]
fn a_csg_solid_whose_scale_swallows_its_detail_is_warned_about() {
    let solid = |far: &str| {
        format!(
            "[[shapes]]\ntype = \"csg\"\nop = \"union\"\nmaterial = \"m\"\nchildren = [\n  \
             {{ type = \"csg\", op = \"difference\", children = [ {{ type = \"box\", min = [-1, 0, -1], max = [1, 1, 1] }}, \
             {{ type = \"box\", min = [-0.5, 0.9, -2], max = [0.5, 2, 2] }} ] }},\n  \
             {{ type = \"sphere\", center = [{far}, 0.5, -50], radius = 0.1 }},\n]\n"
        )
    };
    for (far, warned) in [("1e6", true), ("1e5", true), ("0", false), ("1e3", false)] {
        let extra = solid(far);
        let s = parse_scene(Path::new("e.toml"), &format!("{BASE}{extra}")).unwrap();
        assert_eq!(s.prims.len(), 1);
        let w: Vec<_> = s.warnings.iter().filter(|w| w.contains("its detail may be lost")).collect();
        assert_eq!(w.len(), warned as usize, "sphere at {far}: {:?}", s.warnings);
        if warned {
            let at = format!("e.toml:{}:", line_of(&extra, "type = \"csg\"") - 1);
            assert!(w[0].starts_with(&at) && w[0].contains("`shapes[0]`"), "{}", w[0]);
        }
    }
}

/// A leaf's thickness is measured in its own frame, not on its world-axis bounds: a fin 1e-4 thick in a
/// solid 100 from the origin (tolerance 1e-3) is warned of unturned, turned 1 or 30 degrees about y (a
/// trial's turned fins were not: their bounds are up to 0.5 thick), and as a sheared box (turned, then
/// scaled along x by a parent); the same fin 0.02 thick is warned of in none of these placements.
#[test]
fn a_turned_thin_leaf_is_warned_about() {
    let fin = |w: f64, turn: &str, parent: &str| {
        format!(
            "[[shapes]]\ntype = \"csg\"\nop = \"union\"\nmaterial = \"m\"\ntransform = {{ {parent}translate = [100, 0, 0] }}\n\
             children = [ {{ type = \"box\", min = [-0.5, 0, -0.5], max = [0.5, 0.2, 0.5] }}, \
             {{ type = \"box\", min = [{}, 0.2, -0.5], max = [{}, 0.9, 0.5], transform = {{ rotate = [0, {turn}, 0] }} }} ]\n",
            -w / 2.0,
            w / 2.0
        )
    };
    for (turn, parent, want) in
        [("0", "", 1e-4), ("1", "", 1e-4), ("30", "", 1e-4), ("30", "scale = [2, 1, 1], ", 1e-4 / (0.25f64 * 0.75 + 0.25).sqrt())]
    {
        for (w, warned) in [(1e-4, true), (0.02, false)] {
            let extra = fin(w, turn, parent);
            let s = parse_scene(Path::new("e.toml"), &format!("{BASE}{extra}")).unwrap();
            let found: Vec<_> = s.warnings.iter().filter(|m| m.contains("its detail may be lost")).collect();
            assert_eq!(found.len(), usize::from(warned), "fin {w} turned {turn} ({parent}): {:?}", s.warnings);
            if warned {
                // (The sheared fin: its faces 1e-4 / |(cos 30 / 2, 0, sin 30)| apart.)
                let said: f64 = found[0].split("only ").nth(1).and_then(|r| r.split(' ').next()).unwrap().parse().unwrap();
                assert!((said / (want * w / 1e-4) - 1.0).abs() < 1e-3, "said {said}, want {want}: {}", found[0]);
                assert!(found[0].starts_with(&format!("e.toml:{}:", line_of(&extra, "type = \"csg\"") - 1)), "{}", found[0]);
            }
        }
    }
}

/// Parts a CSG solid's operations leave thinner than the tolerance its rays can use (each leaf thick) are
/// warned of at the solid's line, with their thickness: a trial's cup of walls and floor 1e-4 thick on a
/// base plate lost three walls and its floor 20 from the origin with nothing said (fine at the origin).
/// Warned: that cup at 10 and 20 (also turned), a ball's shell 1e-4 thick at 20, a skin 5e-6 over a
/// hole at the origin. Not warned: the cup at the origin, its walls 0.01 thick at 20, a lens (a knife
/// edge), a block with a ball touching its top face from inside (thin at a point only), two holes
/// that touch, a box with a flush through hole, all at 20.
#[test]
fn thin_parts_the_operations_leave_are_warned_of() {
    let solid = |op: &str, at: &str, children: &str| {
        format!("[[shapes]]\ntype = \"csg\"\nop = \"{op}\"\nmaterial = \"m\"\ntransform = {{ {at} }}\nchildren = [ {children} ]\n")
    };
    let cup = |w: f64| {
        format!(
            "{{ type = \"csg\", op = \"difference\", children = [ {{ type = \"box\", min = [-1, 0, -1], max = [1, 1, 1] }}, \
             {{ type = \"box\", min = [{a}, {w}, {a}], max = [{b}, 1, {b}] }} ] }}, {{ type = \"box\", min = [-1, -0.5, -1], max = [1, 0, 1] }}",
            a = -1.0 + w,
            b = 1.0 - w
        )
    };
    let far = "translate = [20, 0, 0]";
    let cases = [
        (solid("union", "translate = [0, 0, 0]", &cup(1e-4)), None),
        (solid("union", "translate = [10, 0, 0]", &cup(1e-4)), Some(1e-4)),
        (solid("union", far, &cup(1e-4)), Some(1e-4)),
        (solid("union", &format!("rotate = [20, 30, 0], {far}"), &cup(1e-4)), Some(1e-4)),
        (solid("union", far, &cup(0.01)), None),
        (
            solid("difference", far, "{ type = \"sphere\", center = [0, 0, 0], radius = 1 }, { type = \"sphere\", center = [0, 0, 0], radius = 0.9999 }"),
            Some(1e-4),
        ),
        (
            solid(
                "difference",
                "translate = [0, 0, 0]",
                "{ type = \"box\", min = [-0.5, 0, -0.5], max = [0.5, 0.3, 0.5] }, \
                 { type = \"cylinder\", center = [0, 0.1499975, 0], radius = 0.25, height = 0.299995 }",
            ),
            Some(5e-6),
        ),
        (solid("intersection", far, "{ type = \"sphere\", center = [0, -0.8, 0], radius = 1 }, { type = \"sphere\", center = [0, 0.8, 0], radius = 1 }"), None),
        (solid("difference", far, "{ type = \"box\", min = [-1, -1, -1], max = [1, 1, 1] }, { type = \"sphere\", center = [0, 0.5, 0], radius = 0.5 }"), None),
        (
            solid(
                "difference",
                far,
                "{ type = \"box\", min = [-1, 0, -1], max = [1, 0.2, 1] }, { type = \"cylinder\", center = [-0.3, 0.1, 0], radius = 0.3, height = 0.2 }, \
                 { type = \"cylinder\", center = [0.3, 0.1, 0], radius = 0.3, height = 0.2 }",
            ),
            None,
        ),
        (solid("difference", far, "{ type = \"box\", min = [-1, 0, -1], max = [1, 0.2, 1] }, { type = \"cylinder\", center = [0, 0.1, 0], radius = 0.3, height = 0.2 }"), None),
    ];
    for (extra, want) in cases {
        let s = parse_scene(Path::new("e.toml"), &format!("{BASE}{extra}")).unwrap();
        let said: Vec<_> = s.warnings.iter().filter(|w| w.contains("this CSG solid has a part only")).collect();
        assert_eq!(said.len(), usize::from(want.is_some()), "{extra}: {:?}", s.warnings);
        assert_eq!(s.warnings.len(), said.len(), "{extra}: {:?}", s.warnings);
        if let Some(w) = want {
            let thick: f64 = said[0].split("only ").nth(1).and_then(|r| r.split(' ').next()).unwrap().parse().unwrap();
            assert!((thick / w - 1.0).abs() < 0.02, "{thick} vs {w}: {}", said[0]);
            assert!(said[0].starts_with(&format!("e.toml:{}:1: field `shapes[0]`", line_of(&extra, "[[shapes]]"))), "{}", said[0]);
        }
    }
}

/// Messages a trial found inexact: `children = []` is said to be empty (at the list), not missing;
/// `hole = false` is accepted on any shape (harmless: a top-level box, a top-level solid, a `csg`'s
/// child, a named solid's definition), while `hole = true` there is still an error that names it; a
/// solid that looks empty is not said to be unmet by the probe's rays (the camera may see parts of it).
#[test]
fn empty_children_false_holes_and_empty_looking_solids_read_as_what_they_are() {
    for kind in ["csg\"\nop = \"difference", "group"] {
        let extra = format!("[[shapes]]\ntype = \"{kind}\"\nmaterial = \"m\"\nchildren = [ ]\n");
        let (line, field, msg) = fail(&extra);
        assert_eq!((line, field.as_str()), (line_of(&extra, "children = [ ]"), "shapes[0].children"), "{msg}");
        assert!(msg.starts_with("is empty:") && !msg.contains("missing"), "{msg}");
        let (_, _, msg) = fail(&extra.replace("children = [ ]\n", ""));
        assert!(msg.contains("missing required field"), "{msg}");
    }
    let boxed = "type = \"box\"\nmin = [0, 0, 0]\nmax = [1, 1, 1]\nmaterial = \"m\"\n";
    let kid = "{ type = \"sphere\", center = [0, 0, 0], radius = 0.5, hole = HOLE }";
    let csg = format!("[[shapes]]\ntype = \"csg\"\nop = \"union\"\nmaterial = \"m\"\nchildren = [ {kid}, {kid} ]\n");
    let named = "[solids.b]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 0.5\nhole = HOLE\n[[shapes]]\nuse = \"b\"\nmaterial = \"m\"\n";
    let cases = [
        (format!("[[shapes]]\n{boxed}hole = HOLE\n"), "shapes[0].hole", "only children of a `group` can be holes"),
        (
            format!(
                "[[shapes]]\ntype = \"csg\"\nop = \"union\"\nmaterial = \"m\"\nhole = HOLE\nchildren = [ {} ]\n",
                kid.replace("HOLE", "false")
            ),
            "shapes[0].hole",
            "only children of a `group` can be holes",
        ),
        (csg, "shapes[0].children[0].hole", "`hole = true` only applies to children of a `group`"),
        (named.to_string(), "solids.b.hole", "a named solid is not a hole by itself"),
    ];
    for (extra, field, says) in cases {
        let ok = extra.replace("HOLE", "false");
        let s = parse_scene(Path::new("ok.toml"), &format!("{BASE}{ok}")).unwrap_or_else(|e| panic!("{ok}: {e}"));
        assert!(s.warnings.is_empty() && !s.prims.is_empty(), "{ok}: {:?}", s.warnings);
        let bad = extra.replacen("HOLE", "true", 1).replace("HOLE", "false");
        let (line, got, msg) = fail(&bad);
        assert_eq!((got.as_str(), line), (field, line_of(&bad, "hole = true")), "{msg}");
        assert!(msg.contains(says), "{msg}");
    }
    // A group's child may still say `hole = false`.
    let group = format!("[[shapes]]\ntype = \"group\"\nmaterial = \"m\"\nchildren = [ {} ]\n", kid.replace("HOLE", "false"));
    parse_scene(Path::new("ok.toml"), &format!("{BASE}{group}")).unwrap();
    let extra = "[[shapes]]\ntype = \"csg\"\nop = \"difference\"\nmaterial = \"m\"\nchildren = [ { type = \"sphere\", center = [0, 0, 0], \
                 radius = 1 }, { type = \"sphere\", center = [0, 0, 0], radius = 1.5 } ]\n";
    let s = parse_scene(Path::new("e.toml"), &format!("{BASE}{extra}")).unwrap();
    assert!(
        s.warnings.len() == 1
            && s.warnings[0].contains(
                "looks empty: 1728 probe rays across its bounds found no stretch inside it longer than its coincidence tolerance"
            )
            && !s.warnings[0].contains("met it"),
        "{:?}",
        s.warnings
    );
}

/// A checker finer than an f32 coordinate can resolve over the scene's extent (the pattern is its
/// colour `a` alone there: a fuzzed scale of 1e-30 rendered a plain floor) is warned about at its scale;
/// the shipped scale of a checker floor is not.
#[test]
fn a_checker_finer_than_the_coordinates_resolve_is_warned_about() {
    for (scale, warned) in [("1e-30", true), ("1e-7", true), ("0.5", false), ("1e-5", false)] {
        let checker = format!("checker = {{ a = [0.8, 0.8, 0.8], b = [0.1, 0.1, 0.1], scale = {scale} }}");
        let text = BASE.replace("albedo = [0.5, 0.5, 0.5]", &checker);
        assert!(text.contains("checker = "), "BASE's material moved");
        let s = parse_scene(Path::new("c.toml"), &text).unwrap();
        let w: Vec<_> = s.warnings.iter().filter(|w| w.contains("checker of scale")).collect();
        assert_eq!(w.len(), warned as usize, "scale {scale}: {:?}", s.warnings);
        if warned {
            let line = text.lines().position(|l| l.starts_with("checker = ")).unwrap() + 1;
            assert!(w[0].starts_with(&format!("c.toml:{line}:")) && w[0].contains("materials.m.checker.scale"), "{}", w[0]);
        }
    }
}

/// Errors a newcomer meets first read as the mistake they are: `[lights]` for `[[lights]]`, a missing
/// file (no position), a coordinate beyond the f32 range, a value where a table belongs, a table or key
/// written twice.
#[test]
fn first_mistakes_read_as_what_they_are() {
    let text = format!("{BASE}[lights]\ntype = \"point\"\nposition = [0, 3, 0]\nintensity = [1, 1, 1]\n");
    let e = parse_scene(Path::new("l.toml"), &text).unwrap_err();
    assert!(e.message.contains("write `[[lights]]`"), "{e}");
    assert_eq!(e.line, text.lines().position(|l| l == "[lights]").unwrap() + 1, "{e}");
    let e = strata::scene::load_scene(Path::new("/nonexistent/nope.toml")).unwrap_err();
    assert_eq!(e.to_string().split(": ").next(), Some("/nonexistent/nope.toml"), "{e}");
    assert!(e.to_string().contains("cannot read file"), "{e}");
    let (_, field, msg) = fail("[[shapes]]\ntype = \"sphere\"\ncenter = [1e39, 0, 0]\nradius = 1\nmaterial = \"m\"\n");
    assert_eq!(field, "shapes[0].center");
    assert!(msg.contains("f32 range"), "{msg}");
    // A value where a table belongs names the table as the file writes it, not serde's Rust type.
    let (_, field, msg) = fail("[materials]\nwhite = 3\n");
    // (The full path, as the compiler's own errors give it, since session 41.)
    assert_eq!(field, "materials.white");
    assert!(msg.contains("expected a material table ([materials.NAME]") && !msg.contains("MaterialDef"), "{msg}");
    let (_, field, msg) = fail("[[shapes]]\ntype = \"sphere\"\ntransform = 3\n");
    assert_eq!(field, "shapes[0].transform");
    assert!(msg.contains("expected a transform table") && !msg.contains("TransformDef"), "{msg}");
    // Written twice: a list's header says how to write several entries, another table's says it may
    // appear once, a key that it is given twice.
    let sphere = "type = \"sphere\"\ncenter = [0, 0, 0]\nradius = 1\nmaterial = \"m\"\n";
    let twice = [
        (format!("[shapes]\n{sphere}[shapes]\n{sphere}"), "shapes", "write `[[shapes]]` before each entry"),
        ("[materials.m]\ntype = \"lambert\"\n".to_string(), "materials.m", "table `[materials.m]` is defined twice"),
        ("[[shapes]]\ntype = \"sphere\"\nradius = 1\nradius = 2\n".to_string(), "radius", "`radius` is given twice in one table"),
    ];
    // A value, then a header of the same name: the value's line is named.
    let e = parse_scene(Path::new("v.toml"), &format!("shapes = 3\n{BASE}[[shapes]]\n{sphere}")).unwrap_err();
    assert!(e.message.contains("`shapes` is already given a value at line 1; it cannot also be a table `[[shapes]]`"), "{e}");
    for (extra, want, says) in twice {
        let (line, field, msg) = fail(&extra);
        let text = format!("{BASE}{extra}");
        // At the second of the two.
        let needle = if want == "radius" { "radius = 2" } else { extra.lines().next().unwrap() };
        let second = text.lines().enumerate().filter(|(_, l)| l.starts_with(needle)).map(|(i, _)| i + 1).last().unwrap();
        assert_eq!((field.as_str(), line), (want, second), "{extra}");
        assert!(msg.contains(says), "{msg}");
    }
}

/// Separate glass solids whose sphere surfaces coincide (a water sphere filling a glass block's
/// spherical hole exactly, two equal glass spheres) are warned of at the later shape, naming the other;
/// an overlapping water sphere (the documented way), and a glass sphere equal to an opaque one, are not.
#[test]
fn coincident_glass_sphere_surfaces_are_warned_of() {
    let mats = "[materials.glass]\ntype = \"dielectric\"\nior = 1.5\n[materials.water]\ntype = \"dielectric\"\nior = 1.33\n";
    let block =
        "[[shapes]]\ntype = \"group\"\nmaterial = \"glass\"\nchildren = [ { type = \"box\", min = [-1, -1, -1], max = [1, 1, 1] }, \
                 { type = \"sphere\", center = [0, 0, 0], radius = 0.5, hole = true } ]\n";
    let sphere = |c: &str, r: &str, m: &str| format!("[[shapes]]\ntype = \"sphere\"\ncenter = [{c}]\nradius = {r}\nmaterial = \"{m}\"\n");
    let cases = [
        (format!("{block}{}", sphere("0, 0, 0", "0.5", "water")), Some(("shapes[1]", "shapes[0]"))),
        (format!("{block}{}", sphere("0, 0, 0", "0.52", "water")), None),
        (format!("{}{}", sphere("3, 0, 0", "0.5", "glass"), sphere("3, 0, 0", "0.5", "water")), Some(("shapes[1]", "shapes[0]"))),
        (format!("{}{}", sphere("3, 0, 0", "0.5", "glass"), sphere("3, 0, 0", "0.5", "m")), None),
    ];
    for (shapes, want) in cases {
        check_pair_warning(&format!("{BASE}{mats}{shapes}"), "coincides with one of", "[[shapes]]", want);
    }
    // Twenty equal glass spheres: 19 shapes coincide with an earlier one; 8 are named, then a count.
    let text = format!("{BASE}{mats}{}", sphere("3, 0, 0", "0.5", "glass").repeat(20));
    let s = parse_scene(Path::new("g.toml"), &text).unwrap();
    let w: Vec<_> = s.warnings.iter().filter(|w| w.contains("coincide")).collect();
    assert_eq!(w.len(), 9, "{w:?}");
    assert!(w[8].contains("`shapes[9]`") && w[8].contains("and 11 more shapes from here on"), "{}", w[8]);
}

/// Separate glass shapes whose surfaces meet anywhere (not only equal spheres) are warned of at the later
/// shape, naming the other: water whose cylinder fills a cup's hole exactly (up to a lower level), or
/// only its floor, the
/// same in a box cuvette, a glass block resting on a glass slab. A trial's exactly filled cup rendered
/// its water invisible without a word. Water slightly larger than the hole (the documented way), a glass
/// box resting on an opaque one, and glass apart are not warned of; the equal spheres of the check above
/// are warned of once.
#[test]
fn coincident_glass_surfaces_are_warned_of() {
    let mats = "[materials.glass]\ntype = \"dielectric\"\nior = 1.5\npriority = 3\n\
                [materials.water]\ntype = \"dielectric\"\nior = 1.33\npriority = 1\n";
    let cup = "[[shapes]]\ntype = \"group\"\nmaterial = \"glass\"\nchildren = [ { type = \"cylinder\", center = [0, 0, 0], radius = 0.8, height = 2 }, \
               { type = \"cylinder\", center = [0, 0.2, 0], radius = 0.7, height = 2, hole = true } ]\n";
    // (Up to y = 0.5 from the hole's floor at y = -0.8, or from 0.01 below it.)
    let water = |r: &str, low: f64| {
        format!(
            "[[shapes]]\ntype = \"cylinder\"\ncenter = [0, {}, 0]\nradius = {r}\nheight = {}\nmaterial = \"water\"\n",
            (low + 0.5) / 2.0,
            0.5 - low
        )
    };
    let cuvette =
        "[[shapes]]\ntype = \"group\"\nmaterial = \"glass\"\nchildren = [ { type = \"box\", min = [-1, -1, -1], max = [1, 1, 1] }, \
                   { type = \"box\", min = [-0.9, -0.9, -0.9], max = [0.9, 1.5, 0.9], hole = true } ]\n";
    let boxed = |lo: &str, hi: &str, m: &str| format!("[[shapes]]\ntype = \"box\"\nmin = [{lo}]\nmax = [{hi}]\nmaterial = \"{m}\"\n");
    let cases = [
        (format!("{cup}{}", water("0.7", -0.8)), Some(("shapes[1]", "shapes[0]"))),
        (format!("{cup}{}", water("0.71", -0.8)), Some(("shapes[1]", "shapes[0]"))),
        (format!("{cup}{}", water("0.71", -0.81)), None),
        (format!("{cuvette}{}", boxed("-0.9, -0.9, -0.9", "0.9, 0.5, 0.9", "water")), Some(("shapes[1]", "shapes[0]"))),
        (format!("{cuvette}{}", boxed("-0.91, -0.91, -0.91", "0.91, 0.5, 0.91", "water")), None),
        (
            format!("{}{}", boxed("-2, -1, -2", "2, 0, 2", "glass"), boxed("-0.5, 0, -0.5", "0.5, 1, 0.5", "water")),
            Some(("shapes[1]", "shapes[0]")),
        ),
        (format!("{}{}", boxed("-2, -1, -2", "2, 0, 2", "m"), boxed("-0.5, 0, -0.5", "0.5, 1, 0.5", "water")), None),
        (format!("{}{}", boxed("-2, -1, -2", "2, 0, 2", "glass"), boxed("-0.5, 0.01, -0.5", "0.5, 1, 0.5", "water")), None),
    ];
    for (shapes, want) in cases {
        check_pair_warning(&format!("{BASE}{mats}{shapes}"), "meets one of", "[[shapes]]", want);
    }
    // A water sphere filling a spherical hole exactly: the sphere check's warning alone.
    let block =
        "[[shapes]]\ntype = \"group\"\nmaterial = \"glass\"\nchildren = [ { type = \"box\", min = [-1, -1, -1], max = [1, 1, 1] }, \
                 { type = \"sphere\", center = [0, 0, 0], radius = 0.5, hole = true } ]\n\
                 [[shapes]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 0.5\nmaterial = \"water\"\n";
    let s = parse_scene(Path::new("c.toml"), &format!("{BASE}{mats}{block}")).unwrap();
    assert_eq!(
        s.warnings.iter().filter(|w| w.contains("coincides with one of") || w.contains("meets one of")).count(),
        1,
        "{:?}",
        s.warnings
    );
}

/// The check for glass surfaces that meet finds its pairs through a tree of the shapes' bounds: 3,000
/// separate glass panes in a column (every pair overlapping along x) no longer use up its budget before
/// a touching pair elsewhere is seen (a user trial: no warning at all), and a row of 2,000 touching glass
/// boxes is counted in full. Where the budget does run out (40,000 touching boxes), a warning says where
/// the check stopped.
#[test]
fn glass_surfaces_that_meet_are_found_among_many_shapes() {
    let mats = "[materials.glass]\ntype = \"dielectric\"\nior = 1.5\n[materials.water]\ntype = \"dielectric\"\nior = 1.33\n";
    let boxed =
        |lo: [f32; 3], hi: [f32; 3], m: &str| format!("[[shapes]]\ntype = \"box\"\nmin = {lo:?}\nmax = {hi:?}\nmaterial = \"{m}\"\n");
    let meets = |s: &strata::scene::Scene| s.warnings.iter().filter(|w| w.contains("meets one of")).count();
    let stopped = |s: &strata::scene::Scene| s.warnings.iter().any(|w| w.contains("the check for glass surfaces that meet stopped"));
    let more = |s: &strata::scene::Scene| s.warnings.iter().find(|w| w.contains("have glass surfaces that meet")).cloned();
    // The column of panes, then a slab with water resting on it.
    let mut text = format!("{BASE}{mats}");
    for i in 0..3000 {
        text += &boxed([0.0, 0.0, i as f32], [1.0, 1.0, i as f32 + 0.5], "glass");
    }
    text += &boxed([100.0, 0.0, 0.0], [102.0, 1.0, 2.0], "glass");
    text += &boxed([100.0, 1.0, 0.0], [102.0, 2.0, 2.0], "water");
    let s = parse_scene(Path::new("p.toml"), &text).unwrap();
    assert_eq!(meets(&s), 1, "{:?}", s.warnings);
    assert!(s.warnings.iter().any(|w| w.contains("`shapes[3001]`") && w.contains("`shapes[3000]`")), "{:?}", s.warnings);
    assert!(!stopped(&s));
    // A row of touching boxes: each meets the one before it, 8 named, the rest counted exactly.
    let row = |n: usize| (0..n).map(|i| boxed([i as f32, 0.0, 0.0], [i as f32 + 1.0, 1.0, 1.0], "glass")).collect::<String>();
    let s = parse_scene(Path::new("r.toml"), &format!("{BASE}{mats}{}", row(2000))).unwrap();
    assert_eq!(more(&s).as_deref().map(|w| w.contains("and 1991 more shapes")), Some(true), "{:?}", s.warnings);
    assert!(!stopped(&s));
    // A 200 x 200 grid of touching boxes: the budget runs out, and a warning says where.
    let grid: String = (0..40_000)
        .map(|k| {
            let (x, z) = ((k % 200) as f32, (k / 200) as f32);
            boxed([x, 0.0, z], [x + 1.0, 1.0, z + 1.0], "glass")
        })
        .collect();
    let s = parse_scene(Path::new("g.toml"), &format!("{BASE}{mats}{grid}")).unwrap();
    assert!(stopped(&s), "{:?}", &s.warnings[s.warnings.len().saturating_sub(3)..]);
}

/// Area lights whose surfaces coincide (two equal disks, a quad given twice, also from its opposite
/// corner) are warned of at the later light, naming the other: a ray meets only one of them. Lights
/// apart, of another size, a quad facing the other way, or points at one position (never met by a ray)
/// are not.
#[test]
fn coincident_emitters_are_warned_of() {
    let disk = |c: &str, r: &str| {
        format!("[[lights]]\ntype = \"disk\"\ncenter = [{c}]\nnormal = [0, -1, 0]\nradius = {r}\nradiance = [4, 4, 4]\n")
    };
    let quad = "[[lights]]\ntype = \"quad\"\norigin = [-1, 3, -1]\nu = [2, 0, 0]\nv = [0, 0, 2]\nradiance = [2, 2, 2]\n";
    let point = "[[lights]]\ntype = \"point\"\nposition = [0, 3, 0]\nintensity = [5, 5, 5]\n";
    let quad_as =
        |o: &str, u: &str, v: &str| format!("[[lights]]\ntype = \"quad\"\norigin = {o}\nu = {u}\nv = {v}\nradiance = [2, 2, 2]\n");
    let sphere = "[[shapes]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 1\nmaterial = \"m\"\n";
    let cases = [
        (format!("{}{}", disk("0, 3, 0", "0.5"), disk("0, 3, 0", "0.5")), Some(("lights[1]", "lights[0]"))),
        (format!("{}{}", disk("0, 3, 0", "0.5"), disk("0, 3, 0", "0.25")), None),
        (format!("{}{}", disk("0, 3, 0", "0.5"), disk("0, 3.5, 0", "0.5")), None),
        (format!("{}{}", disk("0, 3, 0", "0.5"), disk("-0.0, 3, -0.0", "0.5")), Some(("lights[1]", "lights[0]"))),
        (format!("{quad}{point}{quad}"), Some(("lights[2]", "lights[0]"))),
        (format!("{point}{point}"), None),
        // The same quad from its opposite corner, from an adjacent one, and with negative zeros; facing
        // the other way (emitting downwards, not up) it is another light.
        (format!("{quad}{}", quad_as("[1, 3, 1]", "[-2, 0, 0]", "[0, 0, -2]")), Some(("lights[1]", "lights[0]"))),
        (format!("{quad}{}", quad_as("[1, 3, -1]", "[0, 0, 2]", "[-2, 0, 0]")), Some(("lights[1]", "lights[0]"))),
        (
            format!(
                "{}{}",
                quad_as("[0, 3, 0]", "[2, 0, 0]", "[0, 0, 2]"),
                quad_as("[-0.0, 3, -0.0]", "[2, -0.0, -0.0]", "[-0.0, -0.0, 2]")
            ),
            Some(("lights[1]", "lights[0]")),
        ),
        (format!("{quad}{}", quad_as("[-1, 3, -1]", "[0, 0, 2]", "[2, 0, 0]")), None),
    ];
    for (lights, want) in cases {
        check_pair_warning(&format!("{BASE}{sphere}{lights}"), "surface coincides with", "[[lights]]", want);
    }
}

/// The scene `text` warns (`needle`) of one coinciding pair `want` = (later, earlier entry), at the later
/// entry's `header` line and naming both, or of none.
fn check_pair_warning(text: &str, needle: &str, header: &str, want: Option<(&str, &str)>) {
    let s = parse_scene(Path::new("c.toml"), text).unwrap();
    let w: Vec<_> = s.warnings.iter().filter(|w| w.contains(needle)).collect();
    match want {
        None => assert!(w.is_empty(), "{text}: {w:?}"),
        Some((at, other)) => {
            assert_eq!(w.len(), 1, "{text}: {:?}", s.warnings);
            // (`shapes[1]`: the second `[[shapes]]` header.)
            let n: usize = at[at.find('[').unwrap() + 1..at.len() - 1].parse().unwrap();
            let line = text.lines().enumerate().filter(|(_, l)| *l == header).nth(n).unwrap().0 + 1;
            assert!(w[0].starts_with(&format!("c.toml:{line}:")), "{}", w[0]);
            assert!(w[0].contains(&format!("`{at}`")) && w[0].contains(&format!("`{other}`")), "{}", w[0]);
        }
    }
}

/// A glass CSG solid is one medium where its parts meet: two glasses among leaves whose bounds overlap
/// (a hole of another glass, a union of two, a thin glass beside a solid one, through a named solid, a
/// material inherited from a node or given where a named solid is used) are an error where the second
/// glass is given, naming both. One glass with opaque leaves (a painted hole), two thin glasses, beads of
/// two glasses apart in one union, and a material on the solid that overrides its children's are valid.
#[test]
fn a_glass_csg_solid_of_two_glasses_is_an_error() {
    let glasses = "[materials.g]\ntype = \"dielectric\"\nior = 1.5\n[materials.h]\ntype = \"dielectric\"\nior = 1.5\n\
                   [materials.t]\ntype = \"dielectric\"\nior = 1.5\nthin = true\n[materials.u]\ntype = \"dielectric\"\nior = 1.3\nthin = true\n";
    let solid = |op: &str, a: &str, b: &str, node: &str| {
        format!(
            "{glasses}[[shapes]]\ntype = \"csg\"\nop = \"{op}\"\n{node}children = [\n  \
             {{ type = \"box\", min = [-1, -1, -1], max = [1, 1, 1], material = \"{a}\" }},\n  \
             {{ type = \"sphere\", center = [0, 0, 0], radius = 0.5, material = \"{b}\" }},\n]\n"
        )
    };
    let named = |use_site: &str, def_material: &str| {
        format!(
            "{glasses}[solids.bead]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 0.5\n{def_material}\
             [[shapes]]\ntype = \"group\"\nchildren = [\n  {{ type = \"box\", min = [-1, -1, -1], max = [1, 1, 1], material = \"g\" }},\n  \
             {{ use = \"bead\", hole = true{use_site} }},\n]\n"
        )
    };
    let node = format!(
        "{glasses}[[shapes]]\ntype = \"csg\"\nop = \"difference\"\nchildren = [\n  \
         {{ type = \"box\", min = [-1, -1, -1], max = [1, 1, 1], material = \"g\" }},\n  \
         {{ type = \"csg\", op = \"union\", material = \"h\", children = [{{ type = \"sphere\", center = [0, 0, 0], radius = 0.5 }}] }},\n]\n"
    );
    let cases = [
        (solid("difference", "g", "h", ""), "shapes[0].children[1].material", "type = \"sphere\""),
        (solid("union", "g", "h", ""), "shapes[0].children[1].material", "type = \"sphere\""),
        (solid("intersection", "t", "g", ""), "shapes[0].children[1].material", "type = \"sphere\""),
        (named("", "material = \"h\"\n"), "solids.bead.material", "material = \"h\""),
        (named(", material = \"h\"", ""), "shapes[0].children[1].material", "use = \"bead\""),
        (node, "shapes[0].children[1].material", "op = \"union\", material = \"h\""),
    ];
    for (text, field, needle) in &cases {
        let (line, f, msg) = fail(text);
        assert_eq!((f.as_str(), line), (*field, line_of(text, needle)), "{msg}");
        assert!(msg.contains("joins the glasses") && msg.contains("one medium") && msg.contains("priority"), "{msg}");
    }
    let (_, _, msg) = fail(&cases[0].0);
    assert!(msg.contains("`g` (given at shapes[0].children[0].material)") && msg.contains("`h` (here)"), "{msg}");
    let beads = format!(
        "{glasses}[[shapes]]\ntype = \"csg\"\nop = \"union\"\nchildren = [\n  \
         {{ type = \"sphere\", center = [-2, 0, 0], radius = 0.5, material = \"g\" }},\n  \
         {{ type = \"sphere\", center = [2, 0, 0], radius = 0.5, material = \"h\" }},\n]\n"
    );
    for ok in [solid("difference", "g", "m", ""), solid("union", "t", "u", ""), solid("difference", "g", "h", "material = \"g\"\n"), beads]
    {
        parse_scene(Path::new("ok.toml"), &format!("{BASE}{ok}")).unwrap_or_else(|e| panic!("{e}\n{ok}"));
    }
}

/// An error inside a named solid is located at the definition and names the use that reached it: a
/// solid without a material used twice, once inside a group that gives one and once where nothing
/// does, fails through the second use, which the message names (field and line).
#[test]
fn an_error_in_a_named_solid_names_the_use_that_reached_it() {
    let extra = "[solids.peg]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 0.5\n\
                 [[shapes]]\ntype = \"group\"\nmaterial = \"m\"\nchildren = [ { use = \"peg\" } ]\n\
                 [[shapes]]\ntype = \"group\"\nchildren = [ { type = \"box\", min = [-1, -1, -1], max = [1, 1, 1], material = \"m\" },\n\
                 { use = \"peg\" } ]\n";
    let (line, field, msg) = fail(extra);
    assert_eq!((field.as_str(), line), ("solids.peg.material", line_of(extra, "[solids.peg]")), "{msg}");
    let use_line = BASE.lines().count() + extra.lines().position(|l| l.starts_with("{ use")).unwrap() + 1;
    assert!(msg.contains(&format!("(reached through `use = \"peg\"` at shapes[1].children[1].use, line {use_line})")), "{msg}");
}

/// A glass box or ball thinner than a few spawn offsets (256 ULPs of its coordinates) where it lies is
/// warned of: rays that enter it start past its far face and count as inside the glass from then on (a
/// 2 mm pane at x = 200 rendered black, a user trial). The same pane at the origin, an opaque one, or a
/// thin-sheet glass (no medium to enter) is not; a rotated pane is measured across its faces.
#[test]
fn thin_glass_far_from_the_origin_is_warned_of() {
    let mats = "[materials.glass]\ntype = \"dielectric\"\nior = 1.5\n[materials.sheet]\ntype = \"dielectric\"\nior = 1.5\nthin = true\n";
    let pane = |x: f64, m: &str, rotate: &str| {
        format!(
            "[[shapes]]\ntype = \"box\"\nmin = [-0.5, -0.5, -0.001]\nmax = [0.5, 0.5, 0.001]\nmaterial = \"{m}\"\n\
             transform = {{ rotate = [{rotate}], translate = [{x}, 0, 0] }}\n"
        )
    };
    let ball = |x: f64, r: f64| format!("[[shapes]]\ntype = \"sphere\"\ncenter = [{x}, 0, 0]\nradius = {r}\nmaterial = \"glass\"\n");
    let cases = [
        (pane(200.0, "glass", "0, 0, 0"), Some("this glass box is only 2.00e-3 thick but reaches 2.01e2 from the origin")),
        (pane(200.0, "glass", "0, 35, 20"), Some("this glass box is only 2.00e-3 thick")),
        (pane(0.0, "glass", "0, 0, 0"), None),
        (pane(200.0, "m", "0, 0, 0"), None),
        (pane(200.0, "sheet", "0, 0, 0"), None),
        (ball(200.0, 1e-3), Some("this glass ball is only 2.00e-3 thick")),
        (ball(2.0, 1e-3), None),
    ];
    for (shapes, want) in cases {
        let s = parse_scene(Path::new("t.toml"), &format!("{BASE}{mats}{shapes}")).unwrap();
        let found: Vec<&String> = s.warnings.iter().filter(|w| w.contains("thick but reaches")).collect();
        match want {
            Some(text) => assert!(found.len() == 1 && found[0].contains(text), "{shapes}: {:?}", s.warnings),
            None => assert!(found.is_empty(), "{shapes}: {:?}", s.warnings),
        }
    }
}

/// A value of the wrong type names its field by the same path as range errors do (`shapes[1].radius`, not
/// `radius`; a user trial): the list entry's index, or the table's name. A key inside an inline table keeps
/// its bare name (the text gives its path no plainer).
#[test]
fn type_errors_name_the_full_path() {
    let sphere = |r: &str| format!("[[shapes]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = {r}\nmaterial = \"m\"\n");
    let (_, field, msg) = fail(&format!("{}{}", sphere("1"), sphere("\"big\"")));
    assert_eq!(field, "shapes[1].radius");
    assert!(msg.contains("invalid type: string \"big\""), "{msg}");
    let (_, field, _) = fail("[materials.paint]\ntype = \"lambert\"\nalbedo = [0.5, \"x\", 0.5]\n");
    assert_eq!(field, "materials.paint.albedo");
    let (_, field, _) = fail("[[shapes]]\ntype = \"csg\"\nop = \"union\"\nchildren = [ { type = \"sphere\", radius = \"x\" } ]\n");
    assert_eq!(field, "radius");
    // Headers written with spaces, and a sub-table of a list's entry.
    let (_, field, _) = fail(&format!("{}[[ shapes ]] # the second\ntype = \"sphere\"\nradius = \"x\"\n", sphere("1")));
    assert_eq!(field, "shapes[1].radius");
    let (_, field, _) = fail(&format!("{}[shapes.transform]\nrotate = \"x\"\n", sphere("1")));
    assert_eq!(field, "shapes[0].transform.rotate");
}

/// Warnings any number of shapes may earn are shown for the first 8 of a kind, then counted in one
/// line at the ninth (a user trial's 20,000 generated solids that look empty printed 20,000 warnings
/// and took 8.4 s to probe): empty solids, solids that look empty (probed up to 64 of them: the count
/// says when it stopped), thin glass far from the origin; each kind counted apart.
#[test]
fn warnings_of_many_shapes_are_counted() {
    let looks_empty = |i: usize| {
        format!(
            "[[shapes]]\ntype = \"csg\"\nop = \"difference\"\nmaterial = \"m\"\nchildren = [ {{ type = \"sphere\", center = [{x}, 0, 0], \
             radius = 0.3 }}, {{ type = \"box\", min = [{}, -1, -1], max = [{}, 1, 1] }} ]\n",
            i as f32 * 3.0 - 1.0,
            i as f32 * 3.0 + 1.0,
            x = i as f32 * 3.0
        )
    };
    let empty = |i: usize| {
        format!(
            "[[shapes]]\ntype = \"csg\"\nop = \"intersection\"\nmaterial = \"m\"\nchildren = [ {{ type = \"sphere\", center = [{}, 5, 0], \
             radius = 0.3 }}, {{ type = \"sphere\", center = [{}, 5, 0], radius = 0.3 }} ]\n",
            i as f32 * 3.0,
            i as f32 * 3.0 + 1.0
        )
    };
    let glass = "[materials.g]\ntype = \"dielectric\"\nior = 1.5\n";
    let thin = |i: usize| format!("[[shapes]]\ntype = \"sphere\"\ncenter = [1e6, {}, 0]\nradius = 1\nmaterial = \"g\"\n", i as f32 * 3.0);
    for (n_looks, n_empty, n_thin) in [(8, 3, 0), (9, 12, 20), (70, 0, 9)] {
        let mut text = format!("{BASE}{glass}");
        for i in 0..n_looks.max(n_empty).max(n_thin) {
            if i < n_looks {
                text += &looks_empty(i);
            }
            if i < n_empty {
                text += &empty(i);
            }
            if i < n_thin {
                text += &thin(i);
            }
        }
        let s = parse_scene(Path::new("e.toml"), &text).unwrap();
        let count = |what: &str| s.warnings.iter().filter(|w| w.contains(what)).count();
        let told = |what: &str| s.warnings.iter().find(|w| w.contains("more shapes from here on") && w.contains(what)).cloned();
        for (n, full, summary) in [
            (n_looks, "this CSG solid looks empty", "CSG solids that look empty"),
            (n_empty, "this CSG solid is empty", "empty CSG solids"),
            (n_thin, "this glass ball is only", "glass balls or boxes thinner"),
        ] {
            assert_eq!(count(full), n.min(8), "{full} ({n} shapes): {:?}", s.warnings);
            match told(summary) {
                // (At most 64 solids are probed: 70 that look empty count as 64.)
                Some(w) => assert!(n > 8 && w.contains(&format!("and {} more shapes", n.min(64) - 8)), "{w} ({n})"),
                None => assert!(n <= 8, "{summary}: {n} shapes, no count: {:?}", s.warnings),
            }
        }
        let stopped = s.warnings.iter().any(|w| w.contains("the probe stops after 64"));
        assert_eq!(stopped, n_looks >= 64, "{:?}", s.warnings);
        // The count is told at the first shape not shown.
        if n_looks > 8 {
            let w = told("CSG solids that look empty").unwrap();
            let ninth = text.match_indices("op = \"difference\"").nth(8).unwrap().0;
            let line = text[..ninth].lines().count() - 1;
            assert!(w.starts_with(&format!("e.toml:{line}:")), "{w} (expected line {line})");
        }
    }
}

/// Error paths where the text is unusual (a user trial): a quoted list header (`[["shapes"]]`) counts
/// as an entry of `shapes`; a key of an inline table opened on an earlier line (TOML 1.1 lets inline
/// tables span lines) is named under the table's key, also under a list's entry; and a header whose
/// name was given as a value in the same entry names that value's line, not an earlier entry's.
#[test]
fn unusual_text_still_gives_the_right_path_and_line() {
    let sphere = "type = \"sphere\"\ncenter = [0, 0, 0]\nradius = 1\nmaterial = \"m\"\n";
    // Three quoted headers, then a plain one whose radius is a string: the fourth shape.
    let extra = format!(
        "[[\"shapes\"]]\n{sphere}[[ 'shapes' ]]\n{sphere}[[\"shapes\"]] # c\n{sphere}[[shapes]]\ntype = \"sphere\"\nradius = \"x\"\n"
    );
    // (The field named, at the line holding `needle`.)
    let named_at = |extra: &str, want: &str, needle: &str| {
        let (line, field, _) = fail(extra);
        assert_eq!((field.as_str(), line), (want, line_of(extra, needle)), "{extra}");
    };
    named_at(&extra, "shapes[3].radius", "radius = \"x\"");
    // Inline tables over several lines: in a material, in a shape's transform (its entry counted).
    let checker =
        "[materials.c]\ntype = \"lambert\"\nalbedo = [0.5, 0.5, 0.5]\nchecker = {\n  a = [0.8, 0.2, 0.2],\n  b = [0.1, \"x\", 0.1],\n}\n";
    named_at(checker, "materials.c.checker.b", "b = [0.1");
    let turned = format!(
        "[[shapes]]\n{sphere}[[shapes]]\n{sphere}transform = {{ # a comment {{ [\n  rotate = [0, 30, 0],\n  scale = [1, 1, true],\n}}\n"
    );
    named_at(&turned, "shapes[1].transform.scale", "scale = [1, 1, true]");
    // A one-line array of inline tables before the error line does not hide the path.
    let after_array =
        "[[shapes]]\ntype = \"csg\"\nop = \"union\"\nchildren = [ { type = \"sphere\", center = [0, 0, 0], radius = 1 } ]\nmaterial = 3\n";
    let (_, field, _) = fail(after_array);
    assert_eq!(field, "shapes[0].material");
    // The same with CRLF line breaks (a review: the header's offset was counted one byte per line short,
    // naming `albedo` alone, and panicking inside a multi-byte character of a header's comment).
    let crlf = |extra: &str| {
        let text = format!("{BASE}{extra}").replace('\n', "\r\n");
        parse_scene(Path::new("w.toml"), &text).unwrap_err()
    };
    let e = crlf("[materials.k]\ntype = \"lambert\"\nalbedo = [0.5, \"x\", 0.5]\n");
    assert_eq!(e.field, "materials.k.albedo");
    let e = crlf(&format!("[[shapes]] # {}\ntype = \"sphere\"\nradius = \"x\"\n", "é".repeat(40)));
    assert_eq!(e.field, "shapes[0].radius");
    let e = crlf(checker);
    assert_eq!((e.field.as_str(), e.line), ("materials.c.checker.b", line_of(checker, "b = [0.1")));
    // `transform = {...}` then `[shapes.transform]` in the second shape, the first with a transform of
    // its own (as a value, then as a header): the second's value line is named.
    for first in ["transform = { translate = [1, 0, 0] }\n", "[shapes.transform]\ntranslate = [1, 0, 0]\n"] {
        let extra = format!("[[shapes]]\n{sphere}{first}\n[[shapes]]\n{sphere}transform = {{ rotate = [0, 30, 0] }}\n[shapes.transform]\nscale = [2, 2, 2]\n");
        let text = format!("{BASE}{extra}");
        let value = text.lines().position(|l| l.starts_with("transform = { rotate")).unwrap() + 1;
        let (line, _, msg) = fail(&extra);
        assert_eq!(line, value + 1, "{msg}");
        assert!(msg.contains(&format!("`transform` is already given a value at line {value}")), "{first}: {msg}");
    }
}

/// A child that is not a shape table is named by its index, on one line or several, nested or not (a
/// trial saw the previous child's last key named, no field, or a fragment of text): a string with the
/// way a named solid is used, a list where a child belongs said as such.
#[test]
fn a_child_that_is_not_a_table_is_named_by_its_index() {
    let boxed = "{ type = \"box\", min = [-1, -1, -1], max = [1, 1, 1], material = \"m\" }";
    let cases = [
        (format!("[[shapes]]\ntype = \"group\"\nchildren = [ {boxed}, \"bolt\" ]\n"), "shapes[0].children[1]", "children", "use = "),
        (
            format!("[[shapes]]\ntype = \"group\"\nchildren = [\n  {boxed},\n  \"bolt\",\n]\n"),
            "shapes[0].children[1]",
            "\"bolt\",",
            "use = ",
        ),
        ("[[shapes]]\ntype = \"group\"\nchildren = [ \"bolt\" ]\n".to_string(), "shapes[0].children[0]", "children", "use = "),
        (
            format!("[[shapes]]\ntype = \"group\"\nchildren = [\n  {boxed},\n  [ {boxed} ],\n]\n"),
            "shapes[0].children[1]",
            "  [ {",
            "a list where a child belongs",
        ),
        (
            format!("[[shapes]]\ntype = \"group\"\nchildren = [ {boxed}, {{ type = \"group\", children = [ {boxed}, 5 ] }} ]\n"),
            "shapes[0].children[1].children[1]",
            "children",
            "expected a shape table",
        ),
        // Not a child: an element of a number array over several lines, by its index.
        (
            "[[shapes]]\ntype = \"sphere\"\nmaterial = \"m\"\nradius = 1\ncenter = [\n  0,\n  \"x\",\n  0]\n".to_string(),
            "shapes[0].center[1]",
            "\"x\"",
            "expected f32",
        ),
    ];
    for (extra, field, needle, says) in cases {
        let msg = fails_at(&[(&extra, field, needle)]).remove(0);
        assert!(msg.contains(says), "{extra}: {msg}");
    }
}

/// A difference of one operand subtracts nothing: valid (the solid is that operand) but most likely a
/// hole left out, so warned of at its `op` (a trial's was silent); two operands, or a union of one, are
/// not. A leaf thinner than an f32 step where it lies (its bounds of no extent) is said so, not `0e0`
/// thick.
#[test]
fn a_difference_of_one_operand_is_warned_about() {
    let block = "{ type = \"box\", min = [-1, -0.5, -1], max = [1, 0.5, 1] }";
    let solid =
        |op: &str, more: &str| format!("[[shapes]]\ntype = \"csg\"\nop = \"{op}\"\nmaterial = \"m\"\nchildren = [ {block}{more} ]\n");
    let hole = ", { type = \"sphere\", center = [0, 0.5, 0], radius = 0.25 }";
    for (extra, warned) in [(solid("difference", ""), true), (solid("difference", hole), false), (solid("union", ""), false)] {
        let s = parse_scene(Path::new("e.toml"), &format!("{BASE}{extra}")).unwrap();
        let w: Vec<_> = s.warnings.iter().filter(|w| w.contains("a difference of one operand subtracts nothing")).collect();
        assert_eq!(w.len(), warned as usize, "{extra}: {:?}", s.warnings);
        if warned {
            assert!(w[0].starts_with(&format!("e.toml:{}:", line_of(&extra, "op = "))) && w[0].contains("`shapes[0].op`"), "{}", w[0]);
        }
    }
    // A named solid's lone difference, used twice: one warning, at its definition.
    let named = format!("[solids.s]\ntype = \"csg\"\nop = \"difference\"\nchildren = [ {block} ]\n[[shapes]]\nuse = \"s\"\nmaterial = \"m\"\n[[shapes]]\nuse = \"s\"\nmaterial = \"m\"\n");
    let s = parse_scene(Path::new("e.toml"), &format!("{BASE}{named}")).unwrap();
    let w: Vec<_> = s.warnings.iter().filter(|w| w.contains("a difference of one operand")).collect();
    assert!(w.len() == 1 && w[0].contains("`solids.s.op`"), "{:?}", s.warnings);
    let extra = solid("difference", &hole.replace("0.25", "1e-9"));
    let s = parse_scene(Path::new("e.toml"), &format!("{BASE}{extra}")).unwrap();
    assert!(s.warnings.iter().any(|w| w.contains("one of its leaves is thinner than f32 resolves where it lies")), "{:?}", s.warnings);
}

/// A material name written under an enclosing material (which overrides it) must still name a
/// material: a CSG child's, a group child's and a named solid's own `material` placed by a `use` that
/// gives one (a trial's `"nope"` was accepted silently there). The error is the one given elsewhere,
/// at the name's line and field. A valid name that is overridden is no error and no warning.
#[test]
fn an_overridden_material_name_must_still_name_a_material() {
    let ball = |m: &str| format!("{{ type = \"sphere\", center = [0, 0, 0], radius = 1{m} }}");
    let node = |kind: &str, child: &str| {
        let op = if kind == "csg" { "op = \"union\"\n" } else { "" };
        format!("[[shapes]]\ntype = \"{kind}\"\n{op}material = \"m\"\nchildren = [\n  {child},\n  {}\n]\n", ball(""))
    };
    let nested = format!("{{ type = \"csg\", op = \"union\", children = [{}] }}", ball(", material = \"nope\""));
    let solid = "[solids.a]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 1\nmaterial = \"nope\"\n";
    let cases = [
        (node("csg", &ball(", material = \"nope\"")), "shapes[0].children[0].material", "nope"),
        (node("group", &ball(", material = \"nope\"")), "shapes[0].children[0].material", "nope"),
        (node("csg", &nested), "shapes[0].children[0].children[0].material", "nope"),
        (format!("{solid}[[shapes]]\nuse = \"a\"\nmaterial = \"m\"\n"), "solids.a.material", "\"nope\""),
        (format!("{solid}{}", node("csg", "{ use = \"a\" }")), "solids.a.material", "\"nope\""),
    ];
    let cases: Vec<(&str, &str, &str)> = cases.iter().map(|(e, f, n)| (e.as_str(), *f, *n)).collect();
    for msg in fails_at(&cases) {
        assert!(msg.starts_with("no material named `nope` (defined: m)"), "{msg}");
    }
    // A valid name under an override: accepted, silently.
    let two = "[materials.n]\ntype = \"mirror\"\n";
    for extra in [
        format!("{two}{}", node("csg", &ball(", material = \"n\""))),
        format!("{two}{}[[shapes]]\nuse = \"a\"\nmaterial = \"m\"\n", solid.replace("nope", "n")),
    ] {
        let s = parse_scene(Path::new("ok.toml"), &format!("{BASE}{extra}")).unwrap_or_else(|e| panic!("{extra}: {e}"));
        assert!(s.warnings.is_empty(), "{extra}: {:?}", s.warnings);
    }
}

/// The 1e15 limit holds for a moving shape over the whole shutter, not at time 0 alone: a sphere
/// moving by 9e14 per unit time reaches 9e15 by the close of a shutter [0, 10], and one moving by 1 by
/// that of [0, 1e30] (both were accepted); the error names the motion, its line and the time. Within
/// the limit over its shutter it is accepted.
#[test]
fn a_moving_shape_is_held_to_the_limit_over_the_whole_shutter() {
    let scene = |shutter: &str, shape: &str| {
        let text = format!("{}{shape}", BASE.replace("fov = 40", &format!("fov = 40\nshutter = {shutter}")));
        (parse_scene(Path::new("m.toml"), &text), text)
    };
    let sphere =
        |motion: &str| format!("[[shapes]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 1\nmaterial = \"m\"\nmotion = {motion}\n");
    let solid = |motion: &str| {
        format!("[solids.p]\ntype = \"box\"\nmin = [-1, -1, -1]\nmax = [1, 1, 1]\nmaterial = \"m\"\n[[shapes]]\nuse = \"p\"\nmotion = {motion}\n")
    };
    for (shutter, shape, time) in [
        ("[0, 10]", sphere("[9e14, 0, 0]"), "at time 10 (camera.shutter's close"),
        ("[0, 1e30]", sphere("[1, 0, 0]"), "at time 1e30 (camera.shutter's close"),
        ("[-10, 0]", sphere("[0, 9e14, 0]"), "at time -10 (camera.shutter's open"),
        ("[0, 1e30]", solid("[0, 0, 1]"), "at time 1e30"),
    ] {
        let (r, text) = scene(shutter, &shape);
        let e = r.err().unwrap_or_else(|| panic!("accepted: shutter {shutter}, {shape}"));
        let line = text.lines().position(|l| l.starts_with("motion")).unwrap() + 1;
        assert_eq!((e.field.as_str(), e.line), ("shapes[0].motion", line), "{e}");
        assert!(e.message.contains(time) && e.message.contains("the limit is 1e15"), "{shutter}: {e}");
    }
    for (shutter, shape) in [("[0, 1]", sphere("[9e14, 0, 0]")), ("[0, 1e10]", sphere("[1, 0, 0]")), ("[0, 1e30]", solid("[0, 0, 0]"))] {
        let (r, _) = scene(shutter, &shape);
        r.unwrap_or_else(|e| panic!("shutter {shutter}, {shape}: {e}"));
    }
}

/// `focus_distance` without an aperture (or with aperture 0) changes nothing in the image: a warning at
/// its line and field says so; with an aperture there is none.
#[test]
fn a_focus_distance_without_an_aperture_is_warned_of() {
    for (camera, warned) in [
        ("focus_distance = 3", true),
        ("aperture = 0\nfocus_distance = 3", true),
        ("aperture = 0.1\nfocus_distance = 3", false),
        ("aperture = 0.1", false),
    ] {
        let text = BASE.replace("fov = 40", &format!("fov = 40\n{camera}"));
        let s = parse_scene(Path::new("f.toml"), &text).unwrap();
        let w: Vec<_> = s.warnings.iter().filter(|w| w.contains("focus_distance has no effect without an aperture > 0")).collect();
        assert_eq!(w.len(), usize::from(warned), "{camera}: {:?}", s.warnings);
        if warned {
            let at = format!("f.toml:{}:", text.lines().position(|l| l.starts_with("focus_distance")).unwrap() + 1);
            assert!(w[0].starts_with(&at) && w[0].contains("`camera.focus_distance`"), "{}", w[0]);
        }
    }
}

/// Messages say what is the case: "an" before a vowel (`an emissive material`); a direction that is
/// not zero but too short to normalise is said so (an exact zero is still "the zero vector"); a
/// camera whose look_at differs from its position by too little is "too close", not "must differ"; a
/// length that underflows f32 to 0 is said to, not "got 0"; `motion` in a named solid's definition is
/// said to be there, not in "a CSG child".
#[test]
fn messages_say_what_the_input_is() {
    let (_, _, msg) = fail("[materials.e]\ntype = \"emissive\"\nradiance = [1, 1, 1]\nalbedo = [0.5, 0.5, 0.5]\n");
    assert!(msg.starts_with("does not apply to an `emissive` material"), "{msg}");
    let (_, _, msg) = fail("[materials.l]\ntype = \"lambert\"\nalbedo = [0.5, 0.5, 0.5]\ntint = [1, 1, 1]\n");
    assert!(msg.starts_with("does not apply to a `lambert` material"), "{msg}");
    // A `use` names all it takes (`allowed: motion, hole` was read as the whole list).
    let (_, field, msg) =
        fail("[solids.a]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 1\n[[shapes]]\nuse = \"a\"\nmaterial = \"m\"\nradius = 2\n");
    assert_eq!(field, "shapes[0].radius");
    assert!(msg.contains("(allowed: material, transform, motion (at the top level), hole (in a group's children))"), "{msg}");

    let camera = |from: &str, to: &str| {
        let text = BASE.replace(from, to);
        (parse_scene(Path::new("c.toml"), &text).map(|_| ()).unwrap_err(), text)
    };
    for (up, short) in [("[0, 1e-30, 0]", true), ("[0, 1e-40, 0]", true), ("[0, 0, 0]", false)] {
        let (e, _) = camera("fov = 40", &format!("fov = 40\nup = {up}"));
        assert_eq!(e.field, "camera.up");
        let says = if short { "is too short to normalise" } else { "must not be the zero vector" };
        assert!(e.message.starts_with(says), "{up}: {}", e.message);
    }
    for (position, close) in [("[0, 0, 1e-20]", true), ("[0, 0, 0]", false)] {
        let (e, text) = camera("position = [0, 1, 5]", &format!("position = {position}"));
        assert_eq!((e.field.as_str(), e.line), ("camera.look_at", text.lines().position(|l| l.starts_with("look_at")).unwrap() + 1));
        let says = if close { "is too close to camera.position to give a viewing direction" } else { "must differ from camera.position" };
        assert!(e.message.starts_with(says), "{position}: {}", e.message);
    }
    for (normal, short) in [("[0, 1e-30, 0]", true), ("[0, 0, 0]", false)] {
        let (_, field, msg) = fail(&format!("[[shapes]]\ntype = \"plane\"\npoint = [0, 0, 0]\nnormal = {normal}\nmaterial = \"m\"\n"));
        assert_eq!(field, "shapes[0].normal");
        let says = if short { "is too short to normalise" } else { "must not be the zero vector" };
        assert!(msg.starts_with(says), "{normal}: {msg}");
    }
    for (radius, says) in [("1e-50", "got 1e-50, which underflows f32 to 0"), ("0", "got 0"), ("-1e-60", "got -1e-60, which underflows")] {
        let (_, field, msg) = fail(&format!("[[shapes]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = {radius}\nmaterial = \"m\"\n"));
        assert_eq!(field, "shapes[0].radius");
        assert!(msg.ends_with(says) || msg.contains(&format!("{says} ")), "{radius}: {msg}");
        assert_eq!(msg.contains("underflows"), radius != "0", "{radius}: {msg}");
    }

    let def = "[solids.a]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 1\nmaterial = \"m\"\nmotion = [1, 0, 0]\n";
    for extra in [def.to_string(), format!("{def}[[shapes]]\nuse = \"a\"\n")] {
        let (line, field, msg) = fail(&extra);
        assert_eq!((field.as_str(), line), ("solids.a.motion", line_of(&extra, "motion")));
        assert!(msg.starts_with("a named solid's definition takes no motion") && !msg.contains("CSG child"), "{msg}");
    }
    let child = "[solids.a]\ntype = \"csg\"\nop = \"union\"\nmaterial = \"m\"\nchildren = [{ type = \"sphere\", radius = 1, motion = [1, 0, 0] }]\n";
    let (_, field, msg) = fail(child);
    assert_eq!(field, "solids.a.children[0].motion");
    assert!(msg.contains("not a CSG child"), "{msg}");
}

/// A profile file without `name` (or with an empty one) is named after its file, not printed blank in
/// the render summary; a given name is kept.
#[test]
fn a_profile_without_a_name_is_named_after_its_file() {
    use strata::scene::Profile;
    let body = "spp = 4\npixel_strategy = \"jittered\"\nlight_samples = 1\nlight_strategy = \"jittered\"\nmax_depth = 4\n";
    for (name, want) in [("", "my_look"), ("name = \"\"\n", "my_look"), ("name = \"quick\"\n", "quick")] {
        let p = Profile::parse(Path::new("some/dir/my_look.toml"), &format!("{name}{body}")).unwrap();
        assert_eq!(p.name, want, "{name:?}");
    }
}

/// CSG leaves are counted as `use`s expand, before any is built, and a scene of more than
/// `MAX_CSG_LEAVES` is an error at the shape (or unused solid) that passes it: a trial's seven levels of
/// named solids, each a union of ten uses of the one before, made 10^7 leaves and aborted out of memory
/// after 25 s. Counts saturate (thirty levels are 10^30), and a shape within the limit can pass it with
/// the shapes before it.
#[test]
fn named_solids_that_expand_past_the_leaf_limit_are_errors() {
    let levels = |n: usize, uses: usize, placed: &str| {
        let mut s = "[solids.l0]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 0.1\nmaterial = \"m\"\n".to_string();
        for i in 1..=n {
            let kids: Vec<String> = (0..uses)
                .map(|j| format!("{{ use = \"l{}\", transform = {{ translate = [{}, 0, 0] }} }}", i - 1, j as f32 * 0.01))
                .collect();
            s += &format!("[solids.l{i}]\ntype = \"csg\"\nop = \"union\"\nchildren = [{}]\n", kids.join(", "));
        }
        s + placed
    };
    let limit = strata::scene::MAX_CSG_LEAVES;
    // 4^10 = 1,048,576 leaves: just past the limit (without the count, built in ~5 s and accepted).
    let cases = [
        (levels(10, 4, "[[shapes]]\nuse = \"l10\"\n"), "shapes[0].use", "use = \"l10\"", "expands to 1048576 CSG leaves;"),
        (levels(7, 10, "[[shapes]]\nuse = \"l7\"\n"), "shapes[0].use", "use = \"l7\"", "expands to 10000000 CSG leaves;"),
        (levels(30, 10, "[[shapes]]\nuse = \"l30\"\n"), "shapes[0].use", "use = \"l30\"", "expands to more than 18446744073709551615"),
        // Inline, the shape is named; unused, the solid.
        (
            levels(7, 10, "[[shapes]]\ntype = \"csg\"\nop = \"union\"\nchildren = [{ use = \"l7\" }]\n"),
            "shapes[0]",
            "[[shapes]]",
            "expands to 10000000 CSG leaves;",
        ),
        // (`big` is checked before the unused solids of fewer leaves, which would each be built first.)
        (
            levels(
                6,
                10,
                &format!(
                    "[solids.big]\ntype = \"csg\"\nop = \"union\"\nchildren = [{}]\n[[shapes]]\nuse = \"l1\"\n",
                    ["{ use = \"l6\" }"; 10].join(", ")
                ),
            ),
            "solids.big",
            "[solids.big]",
            "expands to 10000000 CSG leaves;",
        ),
    ];
    for (extra, field, needle, says) in &cases {
        let (line, got, msg) = fail(extra);
        assert_eq!((got.as_str(), line), (*field, line_of(extra, needle)), "{msg}");
        assert!(msg.contains(says) && msg.contains(&format!("the limit is {limit}")), "{msg}");
    }
    // One sphere, then 10^6 leaves: the second shape passes the limit with the one before it.
    let extra = levels(6, 10, "[[shapes]]\nuse = \"l0\"\n[[shapes]]\nuse = \"l6\"\n");
    let (line, got, msg) = fail(&extra);
    assert_eq!((got.as_str(), line), ("shapes[1].use", line_of(&extra, "use = \"l6\"")), "{msg}");
    assert!(msg.contains("expands to 1000000 CSG leaves, which with the 1 of the shapes before it make more than the limit"), "{msg}");
    // Within the limit: 10^4 leaves are built.
    let s = parse_scene(Path::new("ok.toml"), &format!("{BASE}{}", levels(4, 10, "[[shapes]]\nuse = \"l4\"\n"))).unwrap();
    assert_eq!(s.csg.leaf_count(), 10_000);
}

/// A focus distance too small for f32 at the camera is named at its own line, not blamed on the aperture
/// (a user trial's `focus_distance = 1e-30` with an aperture of 0.1 rendered black, warned of as an
/// aperture 3.9e23 pixels wide): below the rounding of the lens points (here 5 x 2^-23 = 6e-7) the point
/// in focus is lost, an error; where the position's rounding is more than a quarter of a pixel at the
/// focus distance, a warning; the default focus distance (to `look_at`) is named by `look_at`.
#[test]
fn a_focus_distance_too_small_for_f32_is_named() {
    let with = |camera: &str| BASE.replace("fov = 40", &format!("fov = 40\n{camera}"));
    let line = |text: &str, key: &str| text.lines().position(|l| l.starts_with(key)).unwrap() + 1;
    for (camera, field, key) in [
        ("aperture = 0.1\nfocus_distance = 1e-30", "camera.focus_distance", "focus_distance"),
        ("aperture = 0.1\nfocus_distance = 5e-7", "camera.focus_distance", "focus_distance"),
        ("aperture = 0.1", "camera.look_at", "look_at"),
    ] {
        let text = with(camera);
        let text = if key == "look_at" { text.replace("look_at = [0, 0, 0]", "look_at = [0, 1, 4.9999995]") } else { text };
        let e = parse_scene(Path::new("c.toml"), &text).unwrap_err();
        assert_eq!((e.field.as_str(), e.line), (field, line(&text, key)), "{camera}: {e}");
        assert!(e.message.contains("too small for f32 at this camera"), "{e}");
    }
    for (camera, warned) in [("aperture = 0.1\nfocus_distance = 1e-5", true), ("aperture = 0.1\nfocus_distance = 1e-3", false)] {
        let text = with(camera);
        let s = parse_scene(Path::new("c.toml"), &text).unwrap();
        let at = format!("c.toml:{}:", line(&text, "focus_distance"));
        let said = s.warnings.iter().any(|w| w.starts_with(&at) && w.contains("`camera.focus_distance`") && w.contains("1.97 of a pixel"));
        assert_eq!(said, warned, "{camera}: {:?}", s.warnings);
        assert!(!s.warnings.iter().any(|w| w.contains("camera.aperture")), "{camera}: {:?}", s.warnings);
    }
}

/// A light of intensity or radiance [0, 0, 0] gives no light: warned of at its field's line (a user
/// trial's were silent); a light that gives some is not.
#[test]
fn lights_that_give_no_light_are_warned_of() {
    let point = |i: &str| format!("[[lights]]\ntype = \"point\"\nposition = [0, 4, 0]\nintensity = {i}\n");
    let quad = |r: &str| format!("[[lights]]\ntype = \"quad\"\norigin = [-1, 3, -1]\nu = [2, 0, 0]\nv = [0, 0, 2]\nradiance = {r}\n");
    for (extra, field, key) in [
        (point("[0, 0, 0]") + &quad("[1, 1, 1]"), Some("lights[0].intensity"), "intensity"),
        (point("[5, 5, 5]") + &quad("[0, 0, 0]"), Some("lights[1].radiance"), "radiance"),
        (point("[5, 0, 0]") + &quad("[0, 0, 1]"), None, ""),
    ] {
        let text = format!("{BASE}{extra}");
        let s = parse_scene(Path::new("l.toml"), &text).unwrap();
        let w: Vec<&String> = s.warnings.iter().filter(|w| w.contains("gives no light")).collect();
        match field {
            Some(field) => {
                let at = format!("l.toml:{}:", line_of(&extra, &format!("{key} = [0, 0, 0]")));
                assert!(w.len() == 1 && w[0].starts_with(&at) && w[0].contains(&format!("`{field}`")), "{at} {field}: {w:?}");
            }
            None => assert!(w.is_empty(), "{w:?}"),
        }
    }
}

/// A light inside a closed solid that keeps its light in is warned of at the light, naming the solid,
/// and the warning is true: alone in the scene, such a light leaves every pixel black (an opaque sphere,
/// an opaque box around a sphere light, a CSG solid, a glass ball around a point light), while the same
/// light just outside the solid, or in a hole bored through it, or the glass ball under the profile's
/// `transmissive_shadows`, lights the floor and is not warned of.
#[test]
fn lights_inside_solids_are_warned_of_and_the_warning_is_true() {
    use strata::render::render;
    use strata::scene::Profile;
    use strata::wavefront::Settings;
    let mats = "[materials.glass]\ntype = \"dielectric\"\nior = 1.5\n\
                [[shapes]]\ntype = \"plane\"\npoint = [0, -1, 0]\nnormal = [0, 1, 0]\nmaterial = \"m\"\n";
    let sphere = |r: &str, m: &str| format!("[[shapes]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = {r}\nmaterial = \"{m}\"\n");
    let point = |y: &str| format!("[[lights]]\ntype = \"point\"\nposition = [0, {y}, 0]\nintensity = [5, 5, 5]\n");
    let ball_light = "[[lights]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 0.2\nradiance = [5, 5, 5]\n";
    let boxed = |h: &str| format!("[[shapes]]\ntype = \"box\"\nmin = [-{h}, -{h}, -{h}]\nmax = [{h}, {h}, {h}]\nmaterial = \"m\"\n");
    // A ball with a square hole bored along y through its centre (the light in the hole) or off it.
    let bored = |x: f32| {
        format!(
            "[[shapes]]\ntype = \"group\"\nmaterial = \"m\"\nchildren = [ {{ type = \"sphere\", center = [0, 0, 0], radius = 0.5 }}, \
             {{ type = \"box\", min = [{}, -1, -0.1], max = [{}, 1, 0.1], hole = true }} ]\n",
            x - 0.1,
            x + 0.1
        )
    };
    let cases: Vec<(String, Option<&str>, bool)> = vec![
        (format!("{}{}", sphere("0.5", "m"), point("0")), Some("closed opaque solid"), false),
        (format!("{}{}", sphere("0.5", "m"), point("0.6")), None, false),
        (format!("{}{ball_light}", boxed("0.3")), Some("closed opaque solid"), false),
        (format!("{}{ball_light}", boxed("0.15")), None, false),
        (format!("{}{}", bored(0.3), point("0")), Some("closed opaque solid"), false),
        (format!("{}{}", bored(0.0), point("0")), None, false),
        (format!("{}{}", sphere("0.5", "glass"), point("0")), Some("a glass solid"), false),
        (format!("{}{}", sphere("0.5", "glass"), point("0")), Some("a glass solid"), true),
    ];
    for (shapes, warned, transmissive) in cases {
        let text = format!("{BASE}{mats}{shapes}");
        let scene = parse_scene(Path::new("l.toml"), &text).unwrap_or_else(|e| panic!("{e}\n{text}"));
        let says: Vec<&String> = scene.warnings.iter().filter(|w| w.contains("lies inside")).collect();
        match warned {
            Some(what) => {
                assert_eq!(says.len(), 1, "{text}\n{:?}", scene.warnings);
                assert!(says[0].contains(what) && says[0].contains("`lights[0]`") && says[0].contains("`shapes[1]`"), "{}", says[0]);
                let line = text.lines().position(|l| l == "[[lights]]").unwrap() + 1;
                assert!(says[0].contains(&format!("l.toml:{line}:")), "{}", says[0]);
            }
            None => assert!(says.is_empty(), "{text}\n{says:?}"),
        }
        let mut profile = Profile::builtin("preview");
        profile.transmissive_shadows = transmissive;
        let (film, _) = render(&scene, Settings { profile, seed: 1 }, 1);
        let brightest = film.to_rgb().iter().fold(0.0f32, |m, c| m.max(c.max_element()));
        assert_eq!(brightest > 0.0, warned.is_none() || transmissive, "{text}: brightest pixel {brightest}");
    }
    // A moving opaque ball: warned of where it holds the light for the whole shutter (it moves 0.1 about
    // a light 0.05 from its centre), not where the light is out of it for part of it (it moves 1).
    for (motion, warned) in [("0.1", true), ("1", false)] {
        let text = format!(
            "{}shutter = [0, 1]\n{}[[shapes]]\ntype = \"plane\"\npoint = [0, -1, 0]\nnormal = [0, 1, 0]\nmaterial = \"m\"\n\
             [[shapes]]\ntype = \"sphere\"\ncenter = [-0.05, 0, 0]\nradius = 0.4\nmaterial = \"m\"\nmotion = [{motion}, 0, 0]\n{}",
            BASE.replace("[materials.m]", "").replace("type = \"lambert\"\nalbedo = [0.5, 0.5, 0.5]\n", ""),
            "[materials.m]\ntype = \"lambert\"\nalbedo = [0.5, 0.5, 0.5]\n",
            point("0")
        );
        let scene = parse_scene(Path::new("l.toml"), &text).unwrap_or_else(|e| panic!("{e}\n{text}"));
        assert_eq!(scene.warnings.iter().any(|w| w.contains("lies inside `shapes[1]`")), warned, "{text}\n{:?}", scene.warnings);
        let (film, _) = render(&scene, Settings { profile: Profile::builtin("preview"), seed: 1 }, 1);
        let brightest = film.to_rgb().iter().fold(0.0f32, |m, c| m.max(c.max_element()));
        assert_eq!(brightest > 0.0, !warned, "{text}: brightest pixel {brightest}");
    }
}

/// A moving shape shifted far during the shutter (a ball under a shutter of [1000, 1001], which is at
/// the origin mid-shutter) is warned of at its `motion`: its spawn offset follows the shift; the same
/// sweep under [0, 1], and a ball that is far away anyway (its own place sets the offset), are not.
#[test]
fn moving_shapes_shifted_far_are_warned_of() {
    let ball = |x: &str, shutter: &str| {
        format!(
            "{}shutter = {shutter}\n[materials.m]\ntype = \"lambert\"\nalbedo = [0.5, 0.5, 0.5]\n\
             [[shapes]]\ntype = \"sphere\"\ncenter = [{x}, 0, 0]\nradius = 0.5\nmaterial = \"m\"\nmotion = [1, 0, 0]\n",
            BASE.replace("[materials.m]\ntype = \"lambert\"\nalbedo = [0.5, 0.5, 0.5]\n", "")
        )
    };
    for (x, shutter, warned) in [("-1000.5", "[1000, 1001]", true), ("-0.5", "[0, 1]", false), ("5000", "[0, 1]", false)] {
        let text = ball(x, shutter);
        let scene = parse_scene(Path::new("m.toml"), &text).unwrap_or_else(|e| panic!("{e}\n{text}"));
        let says: Vec<&String> = scene.warnings.iter().filter(|w| w.contains("shifted by up to")).collect();
        assert_eq!(says.len(), warned as usize, "{text}\n{:?}", scene.warnings);
        if warned {
            let line = text.lines().position(|l| l.starts_with("motion")).unwrap() + 1;
            assert!(says[0].contains(&format!("m.toml:{line}:")) && says[0].contains("`shapes[0].motion`"), "{}", says[0]);
            assert!(says[0].contains("1.001e3") && says[0].contains("camera.shutter's close"), "{}", says[0]);
        }
    }
}
