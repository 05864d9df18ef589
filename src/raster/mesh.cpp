#include "raster/mesh.h"

#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>

#include "core/parallel.h"

namespace posthaste::raster {
namespace {

// Emit the quad of a face with normal sign `s` along axis d covering [u0, u1] x [v0, v1] in the
// plane at coordinate `w` along d (u = d + 1, v = d + 2 mod 3).
void emit_quad(Mesh &m, int d, int s, float w, float u0, float u1, float v0, float v1, int mat)
{
    const int u = (d + 1) % 3, v = (d + 2) % 3;
    glm::vec3 p[4];
    const float uu[4] = {u0, u1, u1, u0}, vv[4] = {v0, v0, v1, v1};
    for (int i = 0; i < 4; ++i) {
        p[i][d] = w;
        p[i][u] = uu[i];
        p[i][v] = vv[i];
    }
    glm::vec3 n(0.0f), t(0.0f);
    n[d] = float(s);
    t[u] = 1.0f;
    const auto base = std::uint32_t(m.positions.size());
    for (int i = 0; i < 4; ++i) {
        m.positions.push_back(p[i]);
        m.normals.push_back(n);
        m.tangents.push_back(t);
    }
    // cross(e_u, e_v) = e_d, so (0, 1, 2) faces +d.
    if (s > 0) {
        m.triangles.emplace_back(base, base + 1, base + 2);
        m.triangles.emplace_back(base, base + 2, base + 3);
    } else {
        m.triangles.emplace_back(base, base + 2, base + 1);
        m.triangles.emplace_back(base, base + 3, base + 2);
    }
    m.materials.push_back(std::uint8_t(mat));
    m.materials.push_back(std::uint8_t(mat));
}

Mesh mesh_chunk(const VoxelGrid &g, glm::ivec3 c0, bool greedy)
{
    Mesh m;
    const glm::ivec3 c1 = glm::min(c0 + kChunkSize, glm::ivec3(g.nx, g.ny, g.nz));
    bool solid = false;
    for (int y = c0.y; y < c1.y && !solid; ++y) {
        for (int z = c0.z; z < c1.z && !solid; ++z) {
            for (int x = c0.x; x < c1.x; ++x) {
                if (g.at(x, y, z) != 0) {
                    solid = true;
                    break;
                }
            }
        }
    }
    if (!solid) {
        return m;  // all air: no faces
    }
    std::uint8_t mask[kChunkSize * kChunkSize];
    for (int d = 0; d < 3; ++d) {
        const int u = (d + 1) % 3, v = (d + 2) % 3;
        const int nu = c1[u] - c0[u], nv = c1[v] - c0[v];
        for (int s = -1; s <= 1; s += 2) {
            for (int w = c0[d]; w < c1[d]; ++w) {
                bool any = false;
                for (int j = 0; j < nv; ++j) {
                    for (int i = 0; i < nu; ++i) {
                        glm::ivec3 p;
                        p[d] = w;
                        p[u] = c0[u] + i;
                        p[v] = c0[v] + j;
                        glm::ivec3 q = p;
                        q[d] += s;
                        const std::uint8_t a = g.at(p.x, p.y, p.z);
                        const std::uint8_t b = g.at(q.x, q.y, q.z);
                        mask[j * kChunkSize + i] = (a != 0 && b == 0) ? a : 0;
                        any |= mask[j * kChunkSize + i] != 0;
                    }
                }
                if (!any) {
                    continue;
                }
                const float plane = float(s > 0 ? w + 1 : w);
                for (int j = 0; j < nv; ++j) {
                    for (int i = 0; i < nu;) {
                        const std::uint8_t mat = mask[j * kChunkSize + i];
                        if (mat == 0) {
                            ++i;
                            continue;
                        }
                        int wi = 1, hj = 1;
                        if (greedy) {
                            while (i + wi < nu && mask[j * kChunkSize + i + wi] == mat) {
                                ++wi;
                            }
                            bool grow = true;
                            while (grow && j + hj < nv) {
                                for (int k = 0; k < wi; ++k) {
                                    if (mask[(j + hj) * kChunkSize + i + k] != mat) {
                                        grow = false;
                                        break;
                                    }
                                }
                                if (grow) {
                                    ++hj;
                                }
                            }
                        }
                        for (int jj = 0; jj < hj; ++jj) {
                            for (int k = 0; k < wi; ++k) {
                                mask[(j + jj) * kChunkSize + i + k] = 0;
                            }
                        }
                        emit_quad(m,
                                  d,
                                  s,
                                  plane,
                                  float(c0[u] + i),
                                  float(c0[u] + i + wi),
                                  float(c0[v] + j),
                                  float(c0[v] + j + hj),
                                  mat);
                        i += wi;
                    }
                }
            }
        }
    }
    m.compute_bounds();
    return m;
}

}  // namespace

void Mesh::compute_bounds()
{
    if (positions.empty()) {
        bounds_min = bounds_max = glm::vec3(0.0f);
        return;
    }
    bounds_min = bounds_max = positions[0];
    for (const glm::vec3 &p : positions) {
        bounds_min = glm::min(bounds_min, p);
        bounds_max = glm::max(bounds_max, p);
    }
}

std::vector<Mesh> mesh_chunks(const VoxelGrid &grid, bool greedy)
{
    const int cx = (grid.nx + kChunkSize - 1) / kChunkSize;
    const int cy = (grid.ny + kChunkSize - 1) / kChunkSize;
    const int cz = (grid.nz + kChunkSize - 1) / kChunkSize;
    std::vector<Mesh> all(std::size_t(cx) * std::size_t(cy) * std::size_t(cz));
    parallel_for(0, int(all.size()), [&](int i) {
        const glm::ivec3 c(i % cx, (i / cx) % cy, i / (cx * cy));
        all[std::size_t(i)] = mesh_chunk(grid, c * kChunkSize, greedy);
    });
    std::vector<Mesh> out;
    for (Mesh &m : all) {
        if (!m.triangles.empty()) {
            out.push_back(std::move(m));
        }
    }
    return out;
}

Mesh mesh_box(const glm::vec3 &min, const glm::vec3 &size, int material)
{
    Mesh m;
    const glm::vec3 max = min + size;
    for (int d = 0; d < 3; ++d) {
        const int u = (d + 1) % 3, v = (d + 2) % 3;
        emit_quad(m, d, -1, min[d], min[u], max[u], min[v], max[v], material);
        emit_quad(m, d, 1, max[d], min[u], max[u], min[v], max[v], material);
    }
    m.compute_bounds();
    return m;
}

Mesh mesh_sphere(float radius, int segments, int material)
{
    Mesh m;
    const int nphi = std::max(segments, 4), ntheta = std::max(segments / 2, 2);
    const float pi = 3.14159265358979323846f;
    for (int j = 0; j <= ntheta; ++j) {
        const float theta = pi * float(j) / float(ntheta);  // from +y down to -y
        for (int i = 0; i <= nphi; ++i) {
            const float phi = 2.0f * pi * float(i) / float(nphi);
            const glm::vec3 n(
                std::sin(theta) * std::cos(phi), std::cos(theta), std::sin(theta) * std::sin(phi));
            m.positions.push_back(n * radius);
            m.normals.push_back(n);
            m.tangents.push_back(glm::vec3(-std::sin(phi), 0.0f, std::cos(phi)));
        }
    }
    const auto row = std::uint32_t(nphi + 1);
    for (int j = 0; j < ntheta; ++j) {
        for (int i = 0; i < nphi; ++i) {
            const std::uint32_t a = std::uint32_t(j) * row + std::uint32_t(i), b = a + 1;
            const std::uint32_t c = a + row, d = c + 1;
            // cross(b - a, c - a) points outward (phi toward +z, theta toward -y).
            if (j != 0) {
                m.triangles.emplace_back(a, b, c);
                m.materials.push_back(std::uint8_t(material));
            }
            if (j != ntheta - 1) {
                m.triangles.emplace_back(b, d, c);
                m.materials.push_back(std::uint8_t(material));
            }
        }
    }
    m.compute_bounds();
    return m;
}

}  // namespace posthaste::raster
