// Inside/outside marking of a CGAL constrained triangulation (faces need info().nesting).
#pragma once

#include <deque>

namespace rheo::mesh::internal {

// Flood fill from `start`; constrained edges are collected in `border` for the next level.
template <typename Tri>
void MarkFrom(Tri& t, typename Tri::Face_handle start, int level,
              std::deque<typename Tri::Edge>& border) {
  if (start->info().nesting != -1) return;
  std::deque<typename Tri::Face_handle> queue{start};
  while (!queue.empty()) {
    auto f = queue.front();
    queue.pop_front();
    if (f->info().nesting != -1) continue;
    f->info().nesting = level;
    for (int i = 0; i < 3; ++i) {
      auto n = f->neighbor(i);
      if (n->info().nesting != -1) continue;
      if (t.is_constrained(typename Tri::Edge(f, i)))
        border.emplace_back(f, i);
      else
        queue.push_back(n);
    }
  }
}

// nesting = number of constraints crossed from the outside; odd means inside the polygon.
template <typename Tri>
void MarkDomains(Tri& t) {
  for (auto f = t.all_faces_begin(); f != t.all_faces_end(); ++f) f->info().nesting = -1;
  std::deque<typename Tri::Edge> border;
  MarkFrom(t, t.infinite_face(), 0, border);
  while (!border.empty()) {
    auto e = border.front();
    border.pop_front();
    auto n = e.first->neighbor(e.second);
    if (n->info().nesting == -1) MarkFrom(t, n, e.first->info().nesting + 1, border);
  }
}

}  // namespace rheo::mesh::internal
