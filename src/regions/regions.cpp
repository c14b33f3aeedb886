#include "regions/regions.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <set>

namespace curvenet::detail {

std::vector<int> colour_graph(const std::vector<std::vector<int>>& adj) {
  const int n = static_cast<int>(adj.size());
  std::vector<int> order(n);
  for (int i = 0; i < n; ++i)
    order[i] = i;
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) { return adj[a].size() > adj[b].size(); });
  std::vector<int> colour(n, -1);
  for (int v : order) {
    std::set<int> used;
    for (int u : adj[v])
      if (colour[u] >= 0)
        used.insert(colour[u]);
    int c = 0;
    while (used.count(c))
      ++c;
    colour[v] = c;
  }
  return colour;
}

std::array<int, 3> palette_colour(int index) {
  static const std::array<std::array<int, 3>, 12> base{{{230, 25, 75},
                                                        {60, 180, 75},
                                                        {255, 225, 25},
                                                        {0, 130, 200},
                                                        {245, 130, 48},
                                                        {145, 30, 180},
                                                        {70, 240, 240},
                                                        {240, 50, 230},
                                                        {210, 245, 60},
                                                        {250, 190, 212},
                                                        {0, 128, 128},
                                                        {170, 110, 40}}};
  if (index < static_cast<int>(base.size()))
    return base[index];
  const double h = std::fmod(0.618033988749895 * index, 1.0) * 6.0;
  const double s = 0.65, v = 0.9, c = v * s, x = c * (1 - std::abs(std::fmod(h, 2.0) - 1)), m = v - c;
  double r = 0, g = 0, b = 0;
  switch (static_cast<int>(h)) {
  case 0:
    r = c;
    g = x;
    break;
  case 1:
    r = x;
    g = c;
    break;
  case 2:
    g = c;
    b = x;
    break;
  case 3:
    g = x;
    b = c;
    break;
  case 4:
    r = x;
    b = c;
    break;
  default:
    r = c;
    b = x;
    break;
  }
  return {static_cast<int>(255 * (r + m)), static_cast<int>(255 * (g + m)), static_cast<int>(255 * (b + m))};
}

RegionResult find_regions(const CutMesh& mesh, const std::vector<std::string>& profile_ids, Coverage coverage,
                          const std::vector<int>& face_component) {
  const int nf = mesh.num_faces();
  std::vector<int> piece(nf, -1);
  std::vector<double> area;
  std::vector<int> piece_component;
  std::vector<Halfedge> loop; // one face's, reused
  for (int s = 0; s < nf; ++s) {
    if (piece[s] >= 0)
      continue;
    const int id = static_cast<int>(area.size());
    area.push_back(0);
    piece_component.push_back(face_component[mesh.face_origin(Face(s))]);
    std::vector<int> stack{s};
    piece[s] = id;
    while (!stack.empty()) {
      const Face f(stack.back());
      stack.pop_back();
      area[id] += mesh.face_area(f);
      mesh.face_loop(f, loop);
      for (Halfedge h : loop) {
        if (mesh.tag(h).is_curve())
          continue; // a barrier
        const Face g = mesh.face(CutMesh::twin(h));
        if (g.is_valid() && piece[g.idx] < 0) {
          piece[g.idx] = id;
          stack.push_back(g.idx);
        }
      }
    }
  }
  const int npieces = static_cast<int>(area.size());
  std::vector<char> outside(npieces, 0);
  if (coverage == Coverage::Local) {
    // Pieces that reach the mesh boundary are not enclosed by the net.
    for (int f = 0; f < nf; ++f) {
      mesh.face_loop(Face(f), loop);
      for (Halfedge h : loop)
        if (!mesh.tag(h).is_curve() && mesh.is_boundary(CutMesh::twin(h)))
          outside[piece[f]] = 1;
    }
    std::set<int> open_component;
    for (int p = 0; p < npieces; ++p)
      if (outside[p])
        open_component.insert(piece_component[p]);
    std::map<int, int> largest; // mesh component -> piece
    for (int p = 0; p < npieces; ++p) {
      if (open_component.count(piece_component[p]))
        continue; // its outside is known
      auto it = largest.find(piece_component[p]);
      if (it == largest.end() || area[p] > area[it->second])
        largest[piece_component[p]] = p;
    }
    for (const auto& [c, p] : largest)
      outside[p] = 1;
  }
  RegionResult out;
  std::vector<int> region_of_piece(npieces, -1);
  for (int p = 0; p < npieces; ++p)
    if (!outside[p]) {
      region_of_piece[p] = static_cast<int>(out.regions.size());
      out.regions.emplace_back();
      out.regions.back().area = area[p];
    }
  out.face_region.assign(nf, -1);
  std::vector<std::set<std::pair<std::string, char>>> boundary(out.regions.size());
  std::vector<std::set<int>> adjacent(out.regions.size());
  for (int f = 0; f < nf; ++f) {
    const int r = region_of_piece[piece[f]];
    out.face_region[f] = r;
    if (r < 0) {
      out.outside_faces++;
      continue;
    }
    out.regions[r].faces++;
    mesh.face_loop(Face(f), loop);
    for (Halfedge h : loop) {
      const CurveTag& t = mesh.tag(h);
      if (!t.is_curve())
        continue;
      boundary[r].insert({profile_ids[t.profile], t.forward ? 'L' : 'R'});
      const Face g = mesh.face(CutMesh::twin(h));
      if (g.is_valid()) {
        const int rg = region_of_piece[piece[g.idx]];
        if (rg >= 0 && rg != r)
          adjacent[r].insert(rg);
      }
    }
  }
  std::vector<std::vector<int>> adj(out.regions.size());
  for (size_t r = 0; r < out.regions.size(); ++r) {
    out.regions[r].boundary.assign(boundary[r].begin(), boundary[r].end());
    adj[r].assign(adjacent[r].begin(), adjacent[r].end());
  }
  const auto colours = colour_graph(adj);
  for (size_t r = 0; r < out.regions.size(); ++r)
    out.regions[r].colour = colours[r];
  return out;
}

} // namespace curvenet::detail
