//! Copying GPU buffers back to the host.

use crate::error::{Error, Result};

use super::Gpu;

/// A buffer of `size` bytes that a query set resolves into, to be copied to a [`Staging`].
pub fn resolve_buffer(gpu: &Gpu, label: &str, size: u64) -> wgpu::Buffer {
    gpu.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size,
        usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
        mapped_at_creation: false,
    })
}

/// A host-readable copy of a GPU buffer, filled by [`Staging::copy`] in a command encoder and
/// read after submission by [`Staging::read`].
pub struct Staging {
    buffer: wgpu::Buffer,
    size: u64,
}

impl Staging {
    pub fn new(gpu: &Gpu, label: &str, size: u64) -> Staging {
        let buffer = gpu.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        Staging { buffer, size }
    }

    /// Records a copy of the first `size` bytes of `src` into this staging buffer.
    pub fn copy(&self, encoder: &mut wgpu::CommandEncoder, src: &wgpu::Buffer) {
        self.copy_from(encoder, src, 0);
    }

    /// Records a copy of `size` bytes of `src` from byte `offset` into this staging buffer.
    pub fn copy_from(&self, encoder: &mut wgpu::CommandEncoder, src: &wgpu::Buffer, offset: u64) {
        encoder.copy_buffer_to_buffer(src, offset, &self.buffer, 0, self.size);
    }

    /// Records a copy of a whole single-layer texture of `rows` rows of `bytes_per_row` bytes
    /// (a multiple of 256, as buffer copies require) into this staging buffer.
    pub fn copy_texture(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        texture: &wgpu::Texture,
        bytes_per_row: u32,
    ) {
        encoder.copy_texture_to_buffer(
            texture.as_image_copy(),
            wgpu::TexelCopyBufferInfo {
                buffer: &self.buffer,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(bytes_per_row),
                    rows_per_image: None,
                },
            },
            texture.size(),
        );
    }

    /// Waits for the GPU and returns the bytes (call after the copy was submitted).
    pub fn read(&self, gpu: &Gpu) -> Result<Vec<u8>> {
        let (tx, rx) = std::sync::mpsc::channel();
        self.buffer.map_async(wgpu::MapMode::Read, .., move |r| {
            // The receiver waits below; a send can only fail if it is gone.
            let _ = tx.send(r);
        });
        gpu.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| Error::Gpu(format!("waiting for readback: {e}")))?;
        rx.recv()
            .map_err(|_| Error::Gpu("readback callback never ran".into()))?
            .map_err(|e| Error::Gpu(format!("mapping readback buffer: {e}")))?;
        let bytes = self
            .buffer
            .get_mapped_range(..)
            .map_err(|e| Error::Gpu(format!("reading readback buffer: {e}")))?
            .to_vec();
        self.buffer.unmap();
        Ok(bytes)
    }
}

/// Reads a buffer of `u32`/`f32`-sized words.
pub fn words<T: bytemuck::Pod>(bytes: &[u8]) -> Vec<T> {
    bytemuck::pod_collect_to_vec(bytes)
}

/// Reads the one `T` at the start of a buffer (a counters struct).
pub fn first<T: bytemuck::Pod>(bytes: &[u8]) -> T {
    bytemuck::pod_read_unaligned(&bytes[..size_of::<T>()])
}

/// Copies whole single-layer textures of 4-byte texels (`T`: `f32` or `u32`) to the host in one
/// submission, and returns each one's texels row by row (the copies' rows are padded to 256
/// bytes, as buffer copies require; the padding is dropped).
pub fn read_texels<T: bytemuck::Pod>(gpu: &Gpu, textures: &[wgpu::Texture]) -> Result<Vec<Vec<T>>> {
    let padded = |t: &wgpu::Texture| (t.width() * 4).div_ceil(256) * 256;
    let stagings: Vec<Staging> = textures
        .iter()
        .map(|t| {
            let bytes = u64::from(padded(t)) * u64::from(t.height());
            Staging::new(gpu, "texture readback", bytes)
        })
        .collect();
    gpu.submit(|e| {
        for (s, t) in stagings.iter().zip(textures) {
            s.copy_texture(e, t, padded(t));
        }
    })?;
    stagings
        .iter()
        .zip(textures)
        .map(|(s, t)| {
            let row = 4 * t.width() as usize;
            let bytes = s.read(gpu)?;
            Ok(bytes
                .chunks(padded(t) as usize)
                .flat_map(|r| words::<T>(&r[..row]))
                .collect())
        })
        .collect()
}
