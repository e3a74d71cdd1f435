// The morph a geomorph vertex shader draws (`regions::VertexMorph`): a straight line from
// where the vertex was shown when its morph started to where it rests.
#define_import_path bevy_aslod::geomorph

// How far a morph started at `start` and taking `1 / inv_duration` seconds has come at
// `time`. A clock that wrapped since the start (Bevy wraps `globals.time` hourly) ends it.
fn progress(time: f32, start: f32, inv_duration: f32) -> f32 {
    let elapsed = time - start;
    if elapsed < 0.0 || inv_duration <= 0.0 {
        return 1.0;
    }
    return clamp(elapsed * inv_duration, 0.0, 1.0);
}

// The position at progress `t` from `first` to `last` (exactly `last` at the end, and
// `first` all along when they are equal).
fn position(first: vec3<f32>, last: vec3<f32>, t: f32) -> vec3<f32> {
    if t >= 1.0 {
        return last;
    }
    return first + (last - first) * t;
}

// The normal at progress `t`, normalised (the end's where the two cancel out).
fn normal(first: vec3<f32>, last: vec3<f32>, t: f32) -> vec3<f32> {
    let n = mix(first, last, t);
    if t >= 1.0 || dot(n, n) <= 1e-12 {
        return last;
    }
    return normalize(n);
}

// The UVs at progress `t` from `first` to `last` (exactly `last` at the end).
fn uv(first: vec2<f32>, last: vec2<f32>, t: f32) -> vec2<f32> {
    if t >= 1.0 {
        return last;
    }
    return first + (last - first) * t;
}

// The tangent at progress `t`: its direction as a normal's from `first`, its handedness the
// end's (`last.w`).
fn tangent(first: vec3<f32>, last: vec4<f32>, t: f32) -> vec4<f32> {
    return vec4<f32>(normal(first, last.xyz, t), last.w);
}
