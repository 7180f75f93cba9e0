// 3MF through lib3mf 1.8 (the v1 C API). Reading walks the build items (and the
// components objects they name) in order, applies their transforms and takes the
// unit the file states. Each mesh object becomes a group named after the object.
#include "import_internal.hpp"

#include <Model/COM/NMR_DLLInterfaces.h>

#include <functional>
#include <memory>

namespace clearfit::detail {
namespace {

using namespace NMR;
using Affine = Eigen::Matrix<double, 3, 4>;  // x' = A·x + t, [A | t]

// Owns a lib3mf handle.
struct Handle {
  PLib3MFBase* p = nullptr;
  Handle() = default;
  Handle(const Handle&) = delete;
  Handle& operator=(const Handle&) = delete;
  ~Handle() {
    if (p) lib3mf_release(p);
  }
  PLib3MFBase** out() { return &p; }
};

std::string last_error(PLib3MFBase* instance) {
  DWORD code = 0;
  LPCSTR message = nullptr;
  if (instance && lib3mf_getlasterror(instance, &code, &message) == LIB3MF_OK && message) return message;
  return "lib3mf error";
}

// Throws InputError(name, element, ...) when a lib3mf call fails.
void check(LIB3MFRESULT result, PLib3MFBase* instance, const std::string& name, const std::string& what) {
  if (result != LIB3MF_OK) throw InputError(name, "", what + ": " + last_error(instance));
}

Affine to_affine(const MODELTRANSFORM& t) {
  Affine a;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 4; ++j) a(i, j) = t.m_fFields[i][j];
  return a;
}

Affine compose(const Affine& outer, const Affine& inner) {
  Affine r;
  r.leftCols<3>() = outer.leftCols<3>() * inner.leftCols<3>();
  r.col(3) = outer.leftCols<3>() * inner.col(3) + outer.col(3);
  return r;
}

std::optional<LengthUnit> unit_of(DWORD unit) {
  switch (unit) {
    case MODELUNIT_MICROMETER: return LengthUnit::micrometre;
    case MODELUNIT_MILLIMETER: return LengthUnit::millimetre;
    case MODELUNIT_CENTIMETER: return LengthUnit::centimetre;
    case MODELUNIT_INCH: return LengthUnit::inch;
    case MODELUNIT_FOOT: return LengthUnit::foot;
    case MODELUNIT_METER: return LengthUnit::metre;
    default: return std::nullopt;
  }
}

DWORD unit_code(LengthUnit unit) {
  switch (unit) {
    case LengthUnit::micrometre: return MODELUNIT_MICROMETER;
    case LengthUnit::millimetre: return MODELUNIT_MILLIMETER;
    case LengthUnit::centimetre: return MODELUNIT_CENTIMETER;
    case LengthUnit::inch: return MODELUNIT_INCH;
    case LengthUnit::foot: return MODELUNIT_FOOT;
    case LengthUnit::metre: return MODELUNIT_METER;
  }
  return MODELUNIT_MILLIMETER;
}

std::string object_name(PLib3MFBase* object) {
  ULONG needed = 0;
  if (lib3mf_object_getnameutf8(object, nullptr, 0, &needed) != LIB3MF_OK || needed == 0) return {};
  std::string s(needed + 1, '\0');
  if (lib3mf_object_getnameutf8(object, s.data(), static_cast<ULONG>(s.size()), &needed) != LIB3MF_OK) return {};
  s.resize(s.find('\0') == std::string::npos ? s.size() : s.find('\0'));
  return s;
}

// Appends one mesh object, transformed, as group `object <id>` or its name.
void append_mesh(RawMesh& raw, PLib3MFBase* object, const Affine& transform, const std::string& name) {
  DWORD id = 0, nv = 0, nt = 0;
  lib3mf_resource_getresourceid(object, &id);
  check(lib3mf_meshobject_getvertexcount(object, &nv), object, name, "cannot read object " + std::to_string(id));
  check(lib3mf_meshobject_gettrianglecount(object, &nt), object, name, "cannot read object " + std::to_string(id));
  std::vector<MODELMESHVERTEX> v(nv);
  std::vector<MODELMESHTRIANGLE> t(nt);
  DWORD got = 0;
  if (nv) check(lib3mf_meshobject_getvertices(object, v.data(), nv, &got), object, name, "cannot read the vertices of object " + std::to_string(id));
  if (nt) check(lib3mf_meshobject_gettriangleindices(object, t.data(), nt, &got), object, name, "cannot read the triangles of object " + std::to_string(id));
  std::string group = object_name(object);
  if (group.empty()) group = "object " + std::to_string(id);
  const int g = raw.group_index(group);
  const int base = static_cast<int>(raw.vertices.size());
  for (const auto& p : v)
    raw.vertices.push_back(transform.leftCols<3>() * Vec3(p.m_fPosition[0], p.m_fPosition[1], p.m_fPosition[2]) +
                           transform.col(3));
  for (const auto& tri : t) {
    std::vector<int> poly(3);
    for (int k = 0; k < 3; ++k)
      poly[k] = tri.m_nIndices[k] < nv ? base + static_cast<int>(tri.m_nIndices[k]) : -1;
    if (poly[0] < 0 || poly[1] < 0 || poly[2] < 0)
      throw InputError(name, "object " + std::to_string(id) + ", triangle " + std::to_string(&tri - t.data()),
                       "vertex index out of range (the object has " + std::to_string(nv) + " vertices)");
    raw.polygons.push_back(std::move(poly));
    raw.polygon_group.push_back(g);
  }
}

// A build item's or component's object: a mesh, or components to descend into.
void append_object(RawMesh& raw, PLib3MFBase* object, const Affine& transform, const std::string& name, int depth) {
  BOOL is_mesh = false, is_components = false;
  lib3mf_object_ismeshobject(object, &is_mesh);
  lib3mf_object_iscomponentsobject(object, &is_components);
  if (is_mesh) return append_mesh(raw, object, transform, name);
  if (!is_components) return;
  if (depth > 32) throw InputError(name, "", "components nest more than 32 levels deep (a cycle?)");
  DWORD count = 0;
  lib3mf_componentsobject_getcomponentcount(object, &count);
  for (DWORD i = 0; i < count; ++i) {
    Handle component, child;
    check(lib3mf_componentsobject_getcomponent(object, i, component.out()), object, name, "cannot read a component");
    check(lib3mf_component_getobjectresource(component.p, child.out()), component.p, name, "cannot read a component's object");
    MODELTRANSFORM t{};
    BOOL has = false;
    lib3mf_component_hastransform(component.p, &has);
    Affine local = Affine::Identity();
    if (has && lib3mf_component_gettransform(component.p, &t) == LIB3MF_OK) local = to_affine(t);
    append_object(raw, child.p, compose(transform, local), name, depth + 1);
  }
}

}  // namespace

RawMesh read_3mf(const std::filesystem::path& path) {
  const std::string name = display(path);
  check_3mf_package(path, name);  // import_3mf_check.cpp: the zip entries' sizes, before lib3mf trusts them
  Handle model, reader;
  if (lib3mf_createmodel(model.out()) != LIB3MF_OK) throw std::runtime_error("lib3mf: cannot create a model");
  check(lib3mf_model_queryreader(model.p, "3mf", reader.out()), model.p, name, "lib3mf has no 3MF reader");
  if (lib3mf_reader_readfromfileutf8(reader.p, path.string().c_str()) != LIB3MF_OK)
    throw InputError(name, "", "lib3mf could not read it: " + last_error(reader.p), "check the file is a valid 3MF package");
  RawMesh raw;
  DWORD warnings = 0;
  lib3mf_reader_getwarningcount(reader.p, &warnings);
  for (DWORD i = 0; i < warnings; ++i) {
    DWORD code = 0;
    ULONG needed = 0;
    std::string text(512, '\0');
    if (lib3mf_reader_getwarningutf8(reader.p, i, &code, text.data(), static_cast<ULONG>(text.size()), &needed) == LIB3MF_OK)
      raw.notes.push_back("lib3mf: " + std::string(text.c_str()) + " (code " + std::to_string(code) + ")");
  }
  DWORD unit = MODELUNIT_MILLIMETER;
  lib3mf_model_getunit(model.p, &unit);
  raw.file_unit = unit_of(unit);
  if (!raw.file_unit) throw InputError(name, "model", "unknown unit code " + std::to_string(unit));

  Handle items;
  check(lib3mf_model_getbuilditems(model.p, items.out()), model.p, name, "cannot list the build items");
  BOOL more = false;
  int n_items = 0;
  while (lib3mf_builditemiterator_movenext(items.p, &more) == LIB3MF_OK && more) {
    Handle item, object;
    check(lib3mf_builditemiterator_getcurrent(items.p, item.out()), items.p, name, "cannot read a build item");
    check(lib3mf_builditem_getobjectresource(item.p, object.out()), item.p, name, "cannot read a build item's object");
    MODELTRANSFORM t{};
    BOOL has = false;
    lib3mf_builditem_hasobjecttransform(item.p, &has);
    Affine transform = Affine::Identity();
    if (has && lib3mf_builditem_getobjecttransform(item.p, &t) == LIB3MF_OK) transform = to_affine(t);
    append_object(raw, object.p, transform, name, 0);
    ++n_items;
  }
  if (n_items == 0) {  // no build: take the mesh objects as they stand
    Handle meshes;
    check(lib3mf_model_getmeshobjects(model.p, meshes.out()), model.p, name, "cannot list the mesh objects");
    while (lib3mf_resourceiterator_movenext(meshes.p, &more) == LIB3MF_OK && more) {
      Handle object;
      check(lib3mf_resourceiterator_getcurrent(meshes.p, object.out()), meshes.p, name, "cannot read a mesh object");
      append_mesh(raw, object.p, Affine::Identity(), name);
    }
    if (!raw.polygons.empty()) raw.notes.push_back("the 3MF has no build items; read its mesh objects untransformed");
  }
  if (raw.groups.empty())
    throw InputError(name, "", "holds no mesh object", "export the part itself (a mesh), not only components or slices");
  return raw;
}

void write_3mf(const Mesh& mesh, const std::filesystem::path& path, LengthUnit unit, const Affine* build_transform) {
  const std::string name = display(path);
  Handle model, writer;
  if (lib3mf_createmodel(model.out()) != LIB3MF_OK) throw std::runtime_error("lib3mf: cannot create a model");
  auto ok = [&](LIB3MFRESULT r, PLib3MFBase* instance, const char* what) {
    if (r != LIB3MF_OK) throw std::runtime_error(std::string(what) + ": " + last_error(instance));
  };
  ok(lib3mf_model_setunit(model.p, unit_code(unit)), model.p, "lib3mf: cannot set the unit");
  MODELTRANSFORM t{};
  if (build_transform)
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 4; ++j) t.m_fFields[i][j] = static_cast<FLOAT>((*build_transform)(i, j));
  const double scale = 1.0 / millimetres_per(unit);
  // One object per run of faces in the same group, so the file keeps the face order.
  const int nf = mesh.num_faces();
  for (int begin = 0; begin < nf;) {
    const int group = mesh.face_group.empty() ? -1 : mesh.face_group[begin];
    int end = begin;
    while (end < nf && (mesh.face_group.empty() ? -1 : mesh.face_group[end]) == group) ++end;
    std::vector<int> local(mesh.vertices.size(), -1);
    std::vector<MODELMESHVERTEX> v;
    std::vector<MODELMESHTRIANGLE> tris;
    auto add_vertex = [&](int vertex) {
      const Vec3 p = mesh.vertices[vertex] * scale;
      v.push_back({{static_cast<FLOAT>(p.x()), static_cast<FLOAT>(p.y()), static_cast<FLOAT>(p.z())}});
      return static_cast<int>(v.size()) - 1;
    };
    for (int f = begin; f < end; ++f) {
      MODELMESHTRIANGLE tri{};
      const auto& c = mesh.faces[f];
      const bool repeats = c[0] == c[1] || c[1] == c[2] || c[0] == c[2];  // 3MF needs 3 distinct indices
      for (int k = 0; k < 3; ++k) {
        int& l = local[c[k]];
        if (l < 0 && !repeats) l = add_vertex(c[k]);
        tri.m_nIndices[k] = static_cast<DWORD>(repeats ? add_vertex(c[k]) : l);
      }
      tris.push_back(tri);
    }
    Handle object, item;
    ok(lib3mf_model_addmeshobject(model.p, object.out()), model.p, "lib3mf: cannot add a mesh object");
    const std::string object_name = group >= 0 ? mesh.groups[group] : "mesh";
    ok(lib3mf_object_setnameutf8(object.p, object_name.c_str()), object.p, "lib3mf: cannot name an object");
    ok(lib3mf_meshobject_setgeometry(object.p, v.data(), static_cast<DWORD>(v.size()), tris.data(),
                                     static_cast<DWORD>(tris.size())),
       object.p, "lib3mf: cannot set an object's geometry");
    ok(lib3mf_model_addbuilditem(model.p, object.p, build_transform ? &t : nullptr, item.out()), model.p,
       "lib3mf: cannot add a build item");
    begin = end;
  }
  ok(lib3mf_model_querywriter(model.p, "3mf", writer.out()), model.p, "lib3mf: no 3MF writer");
  ok(lib3mf_writer_writetofileutf8(writer.p, path.string().c_str()), writer.p, "lib3mf: cannot write the file");
  (void)name;
}

}  // namespace clearfit::detail
