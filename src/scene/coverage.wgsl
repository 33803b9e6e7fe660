// The one coverage rule (mirror of src/scene/coverage.rs; read its module docs): a line
// o + t·d crosses a face when every edge function of its boundary, oriented so that the face
// is seen positively, is > 0; an edge function exactly 0 is broken by the perturbation
// δ = (ε, ε², ε³) of the line. Edges are evaluated from their lexicographically smaller
// endpoint, so that two faces sharing an edge get exactly opposite values.

// `coverage::precedes`: p strictly before q in (x, y, z) order.
fn cov_precedes(p: vec3f, q: vec3f) -> bool {
    return p.x < q.x || (p.x == q.x && (p.y < q.y || (p.y == q.y && p.z < q.z)));
}

// `coverage::lex_positive`.
fn cov_lex_positive(c: vec3f) -> bool {
    if c.x != 0.0 {
        return c.x > 0.0;
    }
    if c.y != 0.0 {
        return c.y > 0.0;
    }
    return c.z > 0.0;
}

// `coverage::edge_function`: d · ((p − o) × (q − o)), exactly antisymmetric in p, q.
fn cov_edge_function(o: vec3f, d: vec3f, p: vec3f, q: vec3f) -> f32 {
    if cov_precedes(q, p) {
        return -dot(d, cross(q - o, p - o));
    }
    return dot(d, cross(p - o, q - o));
}

// `coverage::tie_owner`.
fn cov_tie_owner(d: vec3f, p: vec3f, q: vec3f) -> bool {
    var c = cross(p - q, d);
    var flip = false;
    if cov_precedes(q, p) {
        c = cross(q - p, d);
        flip = true;
    }
    if all(c == vec3f(0.0)) {
        return false;
    }
    return cov_lex_positive(c) != flip;
}

// `coverage::edge_covers`.
fn cov_edge_covers(o: vec3f, d: vec3f, p: vec3f, q: vec3f) -> bool {
    let e = cov_edge_function(o, d, p, q);
    return e > 0.0 || (e == 0.0 && cov_tie_owner(d, p, q));
}

// `coverage::edge_covers` for an edge of a face seen with orientation sign s (d · n): the
// reversed edge when s < 0.
fn cov_edge_covers_oriented(o: vec3f, d: vec3f, p: vec3f, q: vec3f, s: f32) -> bool {
    if s > 0.0 {
        return cov_edge_covers(o, d, p, q);
    }
    return cov_edge_covers(o, d, q, p);
}

// `coverage::edge_function_2d`.
fn cov_edge_function_2d(x: vec2f, p: vec2f, q: vec2f) -> f32 {
    return cov_edge_function(vec3f(x, 0.0), vec3f(0.0, 0.0, 1.0), vec3f(p, 0.0), vec3f(q, 0.0));
}

// `coverage::edge_covers_2d`.
fn cov_edge_covers_2d(x: vec2f, p: vec2f, q: vec2f) -> bool {
    return cov_edge_covers(vec3f(x, 0.0), vec3f(0.0, 0.0, 1.0), vec3f(p, 0.0), vec3f(q, 0.0));
}

// `coverage::triangle_covers_2d`: the three edge functions in xyz, and w = 1 when x is covered.
fn cov_triangle_covers_2d(x: vec2f, a: vec2f, b: vec2f, c: vec2f) -> vec4f {
    let e = vec3f(cov_edge_function_2d(x, b, c), cov_edge_function_2d(x, c, a),
        cov_edge_function_2d(x, a, b));
    let area2 = (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
    var covered = area2 != 0.0;
    let z = vec3f(0.0, 0.0, 1.0);
    var v = array<vec3f, 3>(vec3f(a, 0.0), vec3f(b, 0.0), vec3f(c, 0.0));
    for (var k = 0u; k < 3u; k++) {
        let p = v[(k + 1u) % 3u];
        let q = v[(k + 2u) % 3u];
        if area2 > 0.0 {
            covered = covered && (e[k] > 0.0 || (e[k] == 0.0 && cov_tie_owner(z, p, q)));
        } else {
            covered = covered && (e[k] < 0.0 || (e[k] == 0.0 && cov_tie_owner(z, q, p)));
        }
    }
    return vec4f(e, select(0.0, 1.0, covered));
}
