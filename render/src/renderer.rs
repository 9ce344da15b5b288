//! The GPU side: one wgpu device on Vulkan, offscreen targets per resolution, one
//! submission and one readback per group of views (up to 4 MiB of images).
//!
//! Per view: a render pass into an RGBA8 colour target (cleared to the sky), an R32Float
//! target that receives the optical depth from the fragment shader (cleared to 0, "no hit")
//! and a Depth32Float buffer for visibility (reversed Z: cleared to 0, nearer wins with
//! `Greater`); then both colour targets are copied into one mapped buffer, rows padded to
//! wgpu's 256-byte copy alignment. Views of the same resolution reuse the same textures in
//! turn (commands in one encoder run in order); textures, the uniform buffer and the readback
//! buffer live as long as the renderer and grow only when a call needs more.

use std::collections::HashMap;
use std::sync::{Arc, Mutex, mpsc};

use crate::camera::CameraView;
use crate::error::{RenderError, Result};
use crate::frame::Frame;
use crate::scene::{SKY_RGB, Scene, VERTEX_BYTES};
use crate::tiles::{Tile, frustum_planes, visible_ranges};

const COLOR_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Unorm;
const DEPTH_OUT_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::R32Float;
const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;
/// Bytes per texel of both read-back targets (RGBA8 and R32Float).
const TEXEL_BYTES: u32 = 4;
/// Bytes of one view's uniforms: the clip-from-world matrix.
const VIEW_UNIFORM_BYTES: u64 = 64;

/// Renders [`CameraView`]s of one [`Scene`] offscreen through wgpu on Vulkan (a GPU, or
/// Mesa's lavapipe on the CPU). Holds the device and every buffer between calls: create one
/// per process (or per thread) and call [`Renderer::render`] at camera rate.
///
/// # Guarantees
///
/// The same scene and views give the same bytes on the same adapter and driver (no
/// multisampling, no blending, colours computed on the CPU); different drivers may differ
/// by rasterisation rounding on triangle edges.
#[derive(Debug)]
pub struct Renderer {
    device: wgpu::Device,
    queue: wgpu::Queue,
    adapter_name: String,
    pipeline: wgpu::RenderPipeline,
    view_layout: wgpu::BindGroupLayout,
    uniform_stride: u64,
    vertices: Option<wgpu::Buffer>,
    /// The scene's tiles in the vertex buffer ([`crate::tiles`]): each view draws those in
    /// its frustum.
    tiles: Vec<Tile>,
    /// Reused between views: the vertex ranges of the visible tiles.
    ranges: Vec<std::ops::Range<u32>>,
    /// Triangles drawn by the last call, every view's summed.
    triangles_drawn: u64,
    /// Draw only the tiles in each view's frustum (default); off draws every tile, for
    /// comparisons.
    culling: bool,
    /// The per-view uniforms (one stride each) and their bind group, with room for
    /// `.2` views.
    uniforms: Option<(wgpu::Buffer, wgpu::BindGroup, usize)>,
    targets: HashMap<(u32, u32), Targets>,
    readback: Option<wgpu::Buffer>,
    /// Errors wgpu reports outside a call's result (validation, out of memory): turned into
    /// [`RenderError::Gpu`] by the call that caused them instead of wgpu's default panic.
    errors: Arc<Mutex<Vec<String>>>,
}

/// The offscreen textures of one resolution.
#[derive(Debug)]
struct Targets {
    color: wgpu::Texture,
    color_view: wgpu::TextureView,
    depth_out: wgpu::Texture,
    depth_out_view: wgpu::TextureView,
    depth_view: wgpu::TextureView,
}

/// Where one view's images land in the readback buffer.
struct Slot {
    width: u32,
    height: u32,
    color_offset: u64,
    depth_offset: u64,
}

impl Renderer {
    /// Opens the first Vulkan adapter (a GPU when there is one, else lavapipe) and uploads
    /// `scene`.
    ///
    /// # Errors
    ///
    /// [`RenderError::NoAdapter`] when there is no Vulkan driver (the message says what to
    /// install), [`RenderError::Device`] when the adapter refuses the device.
    pub fn new(scene: &Scene) -> Result<Self> {
        let instance = wgpu::Instance::new(wgpu::InstanceDescriptor {
            backends: wgpu::Backends::VULKAN,
            // No Vulkan validation layers or debug labels: they cost time and are not ours to
            // debug; wgpu's own validation always runs.
            flags: wgpu::InstanceFlags::empty(),
            ..wgpu::InstanceDescriptor::new_without_display_handle()
        });
        let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
            power_preference: wgpu::PowerPreference::HighPerformance,
            force_fallback_adapter: false,
            compatible_surface: None,
            ..Default::default()
        }))
        .map_err(|e| RenderError::NoAdapter(e.to_string()))?;
        let adapter_name = adapter.get_info().name;
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("sadesim-render"),
            // WebGPU's default limits, which every adapter offers, are enough: 8192 px
            // textures (MAX_SIDE_PX is 4096), 256 MiB buffers (the largest readback is one
            // 4096 x 4096 view, 128 MiB, as views are read back in groups of 4 MiB).
            ..Default::default()
        }))
        .map_err(|e| RenderError::Device { adapter: adapter_name.clone(), reason: e.to_string() })?;
        let errors = Arc::new(Mutex::new(Vec::new()));
        let sink = Arc::clone(&errors);
        device.on_uncaptured_error(Arc::new(move |e: wgpu::Error| {
            if let Ok(mut errors) = sink.lock() {
                errors.push(e.to_string());
            }
        }));

        let view_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("view"),
            entries: &[wgpu::BindGroupLayoutEntry {
                binding: 0,
                visibility: wgpu::ShaderStages::VERTEX,
                ty: wgpu::BindingType::Buffer {
                    ty: wgpu::BufferBindingType::Uniform,
                    has_dynamic_offset: true,
                    min_binding_size: wgpu::BufferSize::new(VIEW_UNIFORM_BYTES),
                },
                count: None,
            }],
        });
        let pipeline = create_pipeline(&device, &view_layout);
        let uniform_stride =
            VIEW_UNIFORM_BYTES.next_multiple_of(u64::from(device.limits().min_uniform_buffer_offset_alignment));
        let mut renderer = Self {
            device,
            queue,
            adapter_name,
            pipeline,
            view_layout,
            uniform_stride,
            vertices: None,
            tiles: Vec::new(),
            ranges: Vec::new(),
            triangles_drawn: 0,
            culling: true,
            uniforms: None,
            targets: HashMap::new(),
            readback: None,
            errors,
        };
        renderer.set_scene(scene)?;
        Ok(renderer)
    }

    /// The adapter's name, for the log: e.g. `llvmpipe (LLVM 15.0.6, 256 bits)` for lavapipe.
    pub fn adapter_name(&self) -> &str {
        &self.adapter_name
    }

    /// Triangles the last [`Renderer::render`] call drew, every view's summed: the tiles in
    /// each view's frustum ([`crate::tiles`]), out of [`Scene::triangle_count`] per view.
    pub fn triangles_drawn(&self) -> u64 {
        self.triangles_drawn
    }

    /// Turns frustum culling on (the default) or off (every triangle drawn for every view:
    /// the same images, slower; for comparisons and benchmarks).
    pub fn set_culling(&mut self, on: bool) {
        self.culling = on;
    }

    /// Replaces the scene (e.g. markers added or moved); textures and buffers are kept.
    ///
    /// # Errors
    ///
    /// [`RenderError::Gpu`] when the device cannot hold the scene's vertices.
    pub fn set_scene(&mut self, scene: &Scene) -> Result<()> {
        let (bytes, tiles) = scene.tiled_vertex_bytes();
        self.tiles = tiles;
        self.vertices = (!bytes.is_empty()).then(|| {
            let buffer = self.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("scene vertices"),
                size: bytes.len() as u64,
                usage: wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            self.queue.write_buffer(&buffer, 0, &bytes);
            buffer
        });
        self.take_error()
    }

    /// Renders every view, in order: one [`Frame`] per view. Views go to the GPU in groups
    /// of up to 4 MiB of images, one submission and one readback each: small frames share
    /// the fixed cost of a submission, and the readback buffer stays small however many
    /// views a call has (32 views of 640x480 would map 79 MB at once).
    ///
    /// # Errors
    ///
    /// [`RenderError::Gpu`] when the device reports an error (out of memory, device lost).
    pub fn render(&mut self, views: &[CameraView]) -> Result<Vec<Frame>> {
        let mut frames = Vec::new();
        self.render_into(views, &mut frames)?;
        Ok(frames)
    }

    /// As [`Renderer::render`], into `frames` (resized to one per view), reusing their
    /// allocations: at camera rates, fresh frame buffers cost their page faults every call
    /// (about 1 ms a 640x480 frame with lavapipe's 2-core machine, `docs/performance.md`).
    ///
    /// # Errors
    ///
    /// As [`Renderer::render`]; `frames` then holds unspecified images.
    pub fn render_into(&mut self, views: &[CameraView], frames: &mut Vec<Frame>) -> Result<()> {
        self.triangles_drawn = 0;
        frames.truncate(views.len());
        frames.resize_with(views.len(), Frame::default);
        let (mut rest, mut out) = (views, &mut frames[..]);
        while !rest.is_empty() {
            // As many views as fit in READBACK_GROUP_BYTES, at least one.
            let mut bytes = 0;
            let n = rest
                .iter()
                .take_while(|v| {
                    bytes += view_readback_bytes(v);
                    bytes <= READBACK_GROUP_BYTES
                })
                .count()
                .max(1);
            let (group_out, later) = out.split_at_mut(n);
            self.render_group(&rest[..n], group_out)?;
            (rest, out) = (&rest[n..], later);
        }
        Ok(())
    }

    /// Renders `views` (not empty) into `frames` (as many) in one submission and one readback.
    fn render_group(&mut self, views: &[CameraView], frames: &mut [Frame]) -> Result<()> {
        self.ensure_uniforms(views)?;
        let slots = layout_readback(views);
        let total = slots.last().map_or(0, |s| s.depth_offset + padded_row(s.width) * u64::from(s.height));
        for v in views {
            self.ensure_targets(v.model.width(), v.model.height());
        }
        let readback = self.ensure_readback(total);

        let mut encoder =
            self.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("cameras") });
        let (_, bind_group, _) = self.uniforms.as_ref().ok_or_else(|| RenderError::Gpu("no uniforms".to_owned()))?;
        for (i, slot) in slots.iter().enumerate() {
            let targets = &self.targets[&(slot.width, slot.height)];
            {
                let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                    label: Some("camera"),
                    color_attachments: &[
                        Some(wgpu::RenderPassColorAttachment {
                            view: &targets.color_view,
                            depth_slice: None,
                            resolve_target: None,
                            ops: wgpu::Operations { load: wgpu::LoadOp::Clear(sky()), store: wgpu::StoreOp::Store },
                        }),
                        Some(wgpu::RenderPassColorAttachment {
                            view: &targets.depth_out_view,
                            depth_slice: None,
                            resolve_target: None,
                            ops: wgpu::Operations {
                                load: wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT),
                                store: wgpu::StoreOp::Store,
                            },
                        }),
                    ],
                    depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                        view: &targets.depth_view,
                        // Reversed Z: 0 is the far plane.
                        depth_ops: Some(wgpu::Operations {
                            load: wgpu::LoadOp::Clear(0.0),
                            store: wgpu::StoreOp::Discard,
                        }),
                        stencil_ops: None,
                    }),
                    timestamp_writes: None,
                    occlusion_query_set: None,
                    multiview_mask: None,
                });
                if let Some(vertices) = &self.vertices {
                    pass.set_pipeline(&self.pipeline);
                    let offset = u32::try_from(i as u64 * self.uniform_stride)
                        .map_err(|_| RenderError::Gpu(format!("{} views overflow the uniform offsets", views.len())))?;
                    pass.set_bind_group(0, bind_group, &[offset]);
                    pass.set_vertex_buffer(0, vertices.slice(..));
                    if self.culling {
                        visible_ranges(&self.tiles, &frustum_planes(&views[i].clip_from_world()), &mut self.ranges);
                    } else {
                        self.ranges.clear();
                        self.ranges.extend(
                            self.tiles
                                .first()
                                .zip(self.tiles.last())
                                .map(|(first, last)| first.first_vertex..last.first_vertex + last.vertex_count),
                        );
                    }
                    for range in &self.ranges {
                        self.triangles_drawn += u64::from(range.len() as u32 / 3);
                        pass.draw(range.clone(), 0..1);
                    }
                }
            }
            for (texture, offset) in [(&targets.color, slot.color_offset), (&targets.depth_out, slot.depth_offset)] {
                encoder.copy_texture_to_buffer(
                    texture.as_image_copy(),
                    wgpu::TexelCopyBufferInfo {
                        buffer: &readback,
                        layout: wgpu::TexelCopyBufferLayout {
                            offset,
                            bytes_per_row: Some(padded_row(slot.width) as u32),
                            rows_per_image: Some(slot.height),
                        },
                    },
                    wgpu::Extent3d { width: slot.width, height: slot.height, depth_or_array_layers: 1 },
                );
            }
        }
        self.queue.submit([encoder.finish()]);

        let (sender, receiver) = mpsc::channel();
        readback.slice(..total).map_async(wgpu::MapMode::Read, move |r| {
            let _ = sender.send(r);
        });
        self.device.poll(wgpu::PollType::wait_indefinitely()).map_err(|e| RenderError::Gpu(e.to_string()))?;
        self.take_error()?;
        match receiver.recv() {
            Ok(Ok(())) => {}
            Ok(Err(e)) => return Err(RenderError::Gpu(format!("failed to map the readback buffer: {e}"))),
            Err(_) => return Err(RenderError::Gpu("the readback buffer was never mapped".to_owned())),
        }
        {
            let mapped = readback.slice(..total).get_mapped_range().map_err(|e| RenderError::Gpu(e.to_string()))?;
            for (slot, frame) in slots.iter().zip(frames) {
                read_frame(&mapped, slot, frame);
            }
        }
        readback.unmap();
        Ok(())
    }

    /// Writes every view's matrix into the uniform buffer (grown to fit, with its bind group).
    fn ensure_uniforms(&mut self, views: &[CameraView]) -> Result<()> {
        if self.uniforms.as_ref().is_none_or(|(_, _, capacity)| *capacity < views.len()) {
            let capacity = views.len().next_power_of_two();
            let size = capacity as u64 * self.uniform_stride;
            if size > u64::from(u32::MAX) {
                return Err(RenderError::Gpu(format!("{} views in one call are too many", views.len())));
            }
            let buffer = self.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("views"),
                size,
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            let bind_group = self.device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("views"),
                layout: &self.view_layout,
                entries: &[wgpu::BindGroupEntry {
                    binding: 0,
                    resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                        buffer: &buffer,
                        offset: 0,
                        size: wgpu::BufferSize::new(VIEW_UNIFORM_BYTES),
                    }),
                }],
            });
            self.uniforms = Some((buffer, bind_group, capacity));
        }
        let mut bytes = vec![0u8; views.len() * self.uniform_stride as usize];
        for (i, view) in views.iter().enumerate() {
            let at = i * self.uniform_stride as usize;
            for (k, value) in view.clip_from_world().iter().enumerate() {
                bytes[at + 4 * k..at + 4 * k + 4].copy_from_slice(&value.to_le_bytes());
            }
        }
        if let Some((buffer, _, _)) = &self.uniforms {
            self.queue.write_buffer(buffer, 0, &bytes);
        }
        Ok(())
    }

    fn ensure_targets(&mut self, width: u32, height: u32) {
        let device = &self.device;
        self.targets.entry((width, height)).or_insert_with(|| {
            let texture = |label, format, usage| {
                device.create_texture(&wgpu::TextureDescriptor {
                    label: Some(label),
                    size: wgpu::Extent3d { width, height, depth_or_array_layers: 1 },
                    mip_level_count: 1,
                    sample_count: 1,
                    dimension: wgpu::TextureDimension::D2,
                    format,
                    usage,
                    view_formats: &[],
                })
            };
            let copied = wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC;
            let color = texture("color", COLOR_FORMAT, copied);
            let depth_out = texture("optical depth", DEPTH_OUT_FORMAT, copied);
            let depth = texture("depth buffer", DEPTH_FORMAT, wgpu::TextureUsages::RENDER_ATTACHMENT);
            Targets {
                color_view: color.create_view(&Default::default()),
                depth_out_view: depth_out.create_view(&Default::default()),
                depth_view: depth.create_view(&Default::default()),
                color,
                depth_out,
            }
        });
    }

    /// The readback buffer, at least `size` bytes (grown to the largest call so far, never
    /// shrunk).
    fn ensure_readback(&mut self, size: u64) -> wgpu::Buffer {
        if let Some(buffer) = &self.readback
            && buffer.size() >= size
        {
            return buffer.clone();
        }
        let buffer = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("readback"),
            size,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        self.readback = Some(buffer.clone());
        buffer
    }

    fn take_error(&self) -> Result<()> {
        let mut errors = self.errors.lock().map_err(|_| RenderError::Gpu("error log poisoned".to_owned()))?;
        if errors.is_empty() { Ok(()) } else { Err(RenderError::Gpu(std::mem::take(&mut *errors).join("; "))) }
    }
}

/// Where each view's colour and depth land in the readback buffer, one after the other.
fn layout_readback(views: &[CameraView]) -> Vec<Slot> {
    let mut offset = 0;
    views
        .iter()
        .map(|v| {
            let (width, height) = (v.model.width(), v.model.height());
            let image = padded_row(width) * u64::from(height);
            let slot = Slot { width, height, color_offset: offset, depth_offset: offset + image };
            offset += 2 * image;
            slot
        })
        .collect()
}

/// Largest readback of one submission, bytes (why: [`Renderer::render`]).
const READBACK_GROUP_BYTES: u64 = 4 << 20;

/// Bytes one view takes in the readback buffer: colour and depth, padded rows.
fn view_readback_bytes(view: &CameraView) -> u64 {
    2 * padded_row(view.model.width()) * u64::from(view.model.height())
}

/// Bytes of one row in the readback buffer: wgpu copies rows at multiples of 256 bytes.
fn padded_row(width: u32) -> u64 {
    u64::from(width * TEXEL_BYTES).next_multiple_of(u64::from(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT))
}

/// Unpads one view's rows into `frame` (keeping its allocations): RGBA8 -> RGB8,
/// R32Float -> f32 (little-endian, as wgpu's copy lays texels out).
fn read_frame(mapped: &[u8], slot: &Slot, frame: &mut Frame) {
    let (w, h) = (slot.width as usize, slot.height as usize);
    let row = padded_row(slot.width) as usize;
    (frame.width, frame.height) = (slot.width, slot.height);
    frame.rgb.clear();
    frame.rgb.reserve(w * h * 3);
    frame.depth_m.clear();
    frame.depth_m.reserve(w * h);
    for y in 0..h {
        let color = &mapped[slot.color_offset as usize + y * row..][..w * 4];
        for px in color.chunks_exact(4) {
            frame.rgb.extend_from_slice(&px[..3]);
        }
        let depth = &mapped[slot.depth_offset as usize + y * row..][..w * 4];
        frame.depth_m.extend(depth.chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])));
    }
}

/// The clear colour: [`SKY_RGB`] exactly (RGBA8 unorm stores `round(c * 255)`).
fn sky() -> wgpu::Color {
    let [r, g, b] = SKY_RGB.map(|c| f64::from(c) / 255.0);
    wgpu::Color { r, g, b, a: 1.0 }
}

fn create_pipeline(device: &wgpu::Device, view_layout: &wgpu::BindGroupLayout) -> wgpu::RenderPipeline {
    let shader = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("camera shader"),
        source: wgpu::ShaderSource::Wgsl(include_str!("shader.wgsl").into()),
    });
    let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some("camera"),
        bind_group_layouts: &[Some(view_layout)],
        immediate_size: 0,
    });
    let attributes = [
        wgpu::VertexAttribute { format: wgpu::VertexFormat::Float32x3, offset: 0, shader_location: 0 },
        wgpu::VertexAttribute { format: wgpu::VertexFormat::Unorm8x4, offset: 12, shader_location: 1 },
    ];
    device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some("camera"),
        layout: Some(&layout),
        vertex: wgpu::VertexState {
            module: &shader,
            entry_point: Some("vs_main"),
            compilation_options: Default::default(),
            buffers: &[Some(wgpu::VertexBufferLayout {
                array_stride: VERTEX_BYTES,
                step_mode: wgpu::VertexStepMode::Vertex,
                attributes: &attributes,
            })],
        },
        primitive: wgpu::PrimitiveState {
            topology: wgpu::PrimitiveTopology::TriangleList,
            // World triangles are counter-clockwise seen from outside (sadesim_world::mesh);
            // the projection keeps that orientation in NDC (y up). Insides are never drawn.
            front_face: wgpu::FrontFace::Ccw,
            cull_mode: Some(wgpu::Face::Back),
            ..Default::default()
        },
        depth_stencil: Some(wgpu::DepthStencilState {
            format: DEPTH_FORMAT,
            depth_write_enabled: Some(true),
            depth_compare: Some(wgpu::CompareFunction::Greater),
            stencil: Default::default(),
            bias: Default::default(),
        }),
        multisample: Default::default(),
        fragment: Some(wgpu::FragmentState {
            module: &shader,
            entry_point: Some("fs_main"),
            compilation_options: Default::default(),
            targets: &[
                Some(wgpu::ColorTargetState { format: COLOR_FORMAT, blend: None, write_mask: wgpu::ColorWrites::ALL }),
                Some(wgpu::ColorTargetState {
                    format: DEPTH_OUT_FORMAT,
                    blend: None,
                    write_mask: wgpu::ColorWrites::ALL,
                }),
            ],
        }),
        multiview_mask: None,
        cache: None,
    })
}
