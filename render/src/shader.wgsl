// One pipeline for every camera: world ENU positions to clip space by one matrix per view
// (camera.rs, CameraView::clip_from_world), the triangle's precomputed colour (scene.rs)
// and the optical depth z.

struct View {
    clip_from_world: mat4x4<f32>,
}

@group(0) @binding(0) var<uniform> view: View;

struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    // Flat: one colour per triangle, copied exactly (no interpolation rounding).
    @location(0) @interpolate(flat) color: vec4<f32>,
    // The optical z (metres), perspective-correct: exact for the plane of a triangle.
    @location(1) depth_m: f32,
}

@vertex
fn vs_main(@location(0) position_enu_m: vec3<f32>, @location(1) color: vec4<f32>) -> VertexOut {
    var out: VertexOut;
    out.clip = view.clip_from_world * vec4<f32>(position_enu_m, 1.0);
    out.color = color;
    // w = z by construction of the projection.
    out.depth_m = out.clip.w;
    return out;
}

struct FragmentOut {
    @location(0) color: vec4<f32>,
    @location(1) depth_m: f32,
}

@fragment
fn fs_main(in: VertexOut) -> FragmentOut {
    var out: FragmentOut;
    out.color = in.color;
    out.depth_m = in.depth_m;
    return out;
}
