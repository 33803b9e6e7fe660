//! Checks that a `#[repr(C)]` struct uploaded to the GPU has the layout of the WGSL struct it
//! mirrors: the WGSL source is parsed with naga (the shader compiler wgpu itself uses) and
//! the struct's size and every member's byte offset compared with the Rust struct's
//! (`size_of`, `offset_of!`). A field reordered, added, removed or retyped on one side
//! changes an offset or the size and fails the check. Padding members (`pad…`) are left to
//! the size check on both sides. Test-only: every struct declared with
//! [`crate::gpu::pass::gpu_struct`] gets its `layout_mismatches` from here, which each
//! execution's layout test calls on its shader as the pipelines join it.

/// Compares WGSL struct `wgsl_name` of `source` with a Rust struct of `size` bytes whose named
/// fields lie at `fields` (name, byte offset), in declaration order. Returns every mismatch.
pub(crate) fn mismatches(
    source: &str,
    wgsl_name: &str,
    size: usize,
    fields: &[(&str, usize)],
) -> Vec<String> {
    let module = match naga::front::wgsl::parse_str(source) {
        Ok(m) => m,
        Err(e) => return vec![format!("WGSL does not parse: {}", e.emit_to_string(source))],
    };
    let Some((members, span)) = module.types.iter().find_map(|(_, t)| match &t.inner {
        naga::TypeInner::Struct { members, span } if t.name.as_deref() == Some(wgsl_name) => {
            Some((members, *span))
        }
        _ => None,
    }) else {
        return vec![format!("no WGSL struct {wgsl_name}")];
    };
    let mut out = Vec::new();
    if span as usize != size {
        out.push(format!("{wgsl_name}: WGSL size {span}, Rust size {size}"));
    }
    for m in members {
        let name = m.name.as_deref().unwrap_or("?");
        if name.starts_with("pad") {
            continue;
        }
        match fields.iter().find(|(f, _)| *f == name) {
            None => out.push(format!("{wgsl_name}.{name}: no Rust field of that name")),
            Some(&(_, offset)) if offset != m.offset as usize => out.push(format!(
                "{wgsl_name}.{name}: WGSL offset {}, Rust offset {offset}",
                m.offset
            )),
            Some(_) => {}
        }
    }
    for (f, _) in fields {
        if !f.starts_with("pad") && !members.iter().any(|m| m.name.as_deref() == Some(f)) {
            out.push(format!("{wgsl_name}: Rust field {f} is not in WGSL"));
        }
    }
    out
}

/// Fails, naming each mismatch, unless `found` (a struct's `layout_mismatches`) is empty.
pub fn assert_agree(found: Vec<String>) {
    assert!(found.is_empty(), "WGSL layout mismatches: {found:?}");
}

/// The layout test of an execution's GPU structs (declared with
/// [`crate::gpu::pass::gpu_struct`]): a module `layout_tests` whose test
/// `uniforms_match_wgsl` checks every struct after `=>` against every shader before it, each
/// given as the parts its pipeline joins (an array or `Vec` of `&str`). Invoked under
/// `#[cfg(test)]`, as this module is test-only.
macro_rules! layout_test {
    ($($source:expr),+ => $($ty:ident),+) => {
        mod layout_tests {
            use super::*;

            #[test]
            fn uniforms_match_wgsl() {
                for source in [$($source.join("\n")),+] {
                    $($crate::gpu::wgsl_layout::assert_agree($ty::layout_mismatches(&source));)+
                }
            }
        }
    };
}
pub(crate) use layout_test;

#[cfg(test)]
mod tests {
    #[repr(C)]
    struct Pair {
        a: [f32; 3],
        b: u32,
        c: [f32; 4],
    }

    const WGSL: &str = "struct Pair { a: vec3<f32>, b: u32, c: vec4<f32> }";

    #[test]
    fn a_matching_struct_passes() {
        let rust = [
            ("a", std::mem::offset_of!(Pair, a)),
            ("b", std::mem::offset_of!(Pair, b)),
            ("c", std::mem::offset_of!(Pair, c)),
        ];
        let found = super::mismatches(WGSL, "Pair", std::mem::size_of::<Pair>(), &rust);
        assert!(found.is_empty(), "{found:?}");
    }

    /// The check fails when a field is reordered on either side, renamed, or missing.
    #[test]
    fn reordered_fields_are_caught() {
        let size = std::mem::size_of::<Pair>();
        let rust = [
            ("a", std::mem::offset_of!(Pair, a)),
            ("b", std::mem::offset_of!(Pair, b)),
            ("c", std::mem::offset_of!(Pair, c)),
        ];
        assert!(super::mismatches(WGSL, "Pair", size, &rust).is_empty());
        // WGSL reordered: b first moves a to the next 16-byte boundary.
        let reordered = "struct Pair { b: u32, a: vec3<f32>, c: vec4<f32> }";
        let found = super::mismatches(reordered, "Pair", size, &rust);
        assert!(found.iter().any(|m| m.contains("Pair.a")), "{found:?}");
        // Rust reordered (the offsets of a struct declared b, a, c).
        let swapped = [("b", 0), ("a", 4), ("c", 16)];
        let found = super::mismatches(WGSL, "Pair", size, &swapped);
        assert!(found.iter().any(|m| m.contains("Pair.b")), "{found:?}");
        // A Rust field WGSL does not have, and a WGSL struct that is not there.
        let extra = [("a", 0), ("b", 12), ("c", 16), ("d", 32)];
        assert!(!super::mismatches(WGSL, "Pair", 36, &extra).is_empty());
        assert!(!super::mismatches(WGSL, "Other", size, &rust).is_empty());
    }

    crate::gpu::pass::gpu_struct! {
        /// A uniform declared as the executions declare theirs.
        struct View as "View" {
            near: f32 => "f32",
            far: f32 => "f32",
            face: u32 => "u32",
            radius: f32 => "f32",
        }
    }

    /// A struct declared with `gpu_struct!` agrees with its own WGSL, and the check catches a
    /// field reordered on the WGSL side (both fields named) and one removed from it.
    #[test]
    fn a_reordered_wgsl_field_is_rejected() {
        assert!(View::layout_mismatches(View::WGSL).is_empty());
        let swapped = View::WGSL.replace(
            "    near: f32,\n    far: f32,",
            "    far: f32,\n    near: f32,",
        );
        assert_ne!(swapped, View::WGSL, "the struct declares near before far");
        let found = View::layout_mismatches(&swapped);
        assert!(
            found.iter().any(|m| m.starts_with("View.near")),
            "{found:?}"
        );
        assert!(found.iter().any(|m| m.starts_with("View.far")), "{found:?}");
        let removed = View::WGSL.replace("    face: u32,\n", "");
        let found = View::layout_mismatches(&removed);
        assert!(found.iter().any(|m| m.contains("face")), "{found:?}");
    }
}
