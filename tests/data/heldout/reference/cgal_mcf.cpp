// Reference curve skeleton of a closed triangle mesh: CGAL's extract_mean_curvature_flow_skeleton
// with its default parameters. Reads an OFF file, writes "J n" + n lines "x y z r" and "B m" +
// m lines "i j"; r = mean distance from a joint to the mesh vertices CGAL maps to it.
// Build: g++ -O2 -DNDEBUG -std=c++17 -I/usr/include/eigen3 cgal_mcf.cpp -o cgal_mcf -lgmp -lmpfr
#include <CGAL/Simple_cartesian.h>
#include <CGAL/Surface_mesh.h>
#include <CGAL/extract_mean_curvature_flow_skeleton.h>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <map>

typedef CGAL::Simple_cartesian<double> Kernel;
typedef Kernel::Point_3 Point;
typedef CGAL::Surface_mesh<Point> Mesh;
typedef CGAL::Mean_curvature_flow_skeletonization<Mesh> Skeletonization;
typedef Skeletonization::Skeleton Skeleton;

int main(int argc, char** argv) {
  if (argc != 3) { std::cerr << "usage: cgal_mcf IN.off OUT.txt\n"; return 2; }
  Mesh mesh;
  std::ifstream in(argv[1]);
  if (!(in >> mesh) || !CGAL::is_triangle_mesh(mesh) || !CGAL::is_closed(mesh)) {
    std::cerr << "not a closed triangle mesh: " << argv[1] << "\n"; return 1;
  }
  Skeleton skeleton;
  CGAL::extract_mean_curvature_flow_skeleton(mesh, skeleton);
  std::map<Skeleton::vertex_descriptor, std::size_t> index;
  std::FILE* out = std::fopen(argv[2], "w");
  std::fprintf(out, "J %zu\n", (std::size_t)num_vertices(skeleton));
  std::size_t k = 0;
  for (auto v : CGAL::make_range(vertices(skeleton))) {
    index[v] = k++;
    const Point& p = skeleton[v].point;
    double sum = 0; std::size_t n = 0;
    for (auto vd : skeleton[v].vertices) { sum += std::sqrt(CGAL::squared_distance(p, mesh.point(vd))); ++n; }
    std::fprintf(out, "%.17g %.17g %.17g %.17g\n", p.x(), p.y(), p.z(), n ? sum / n : 0.0);
  }
  std::fprintf(out, "B %zu\n", (std::size_t)num_edges(skeleton));
  for (auto e : CGAL::make_range(edges(skeleton)))
    std::fprintf(out, "%zu %zu\n", index[source(e, skeleton)], index[target(e, skeleton)]);
  std::fclose(out);
  return 0;
}
