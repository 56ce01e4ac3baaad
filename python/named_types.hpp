// Arguments and answers that the module holds as Python objects (an array-like it converts itself, an Open3D
// mesh, an integer of any kind, answers that are arrays or Open3D tensors) but names precisely in the
// signatures help() and the stubs show, instead of pybind11's `object`: Named<Tag> takes any object, as
// py::object does, so that the module's own checks raise its errors (naming the argument) and not pybind11's
// "incompatible function arguments" with every argument printed.
#pragma once

#include <pybind11/pybind11.h>

namespace lancer::python {

namespace py = pybind11;

template <class Tag>
struct Named {
    py::object object;
};

// The names, as the stubs (python/lancer.pyi) spell them.
struct ArrayLikeName {
    static constexpr auto name = py::detail::const_name("numpy.typing.ArrayLike");
};
struct TriangleMeshName {
    static constexpr auto name = py::detail::const_name("open3d.t.geometry.TriangleMesh");
};
struct IndexName {
    static constexpr auto name = py::detail::const_name("typing.SupportsIndex");
};
struct AnswerArrayName {
    static constexpr auto name = py::detail::const_name("lancer.Array");
};
struct StateName {  // pickle's (RaycastingScene::pickled, InstancedScene::pickled)
    static constexpr auto name = py::detail::const_name("dict[str, typing.Any]");
};
struct AnswerDictName {
    static constexpr auto name = py::detail::const_name("dict[str, lancer.Array]");
};

using ArrayLike = Named<ArrayLikeName>;

}  // namespace lancer::python

namespace pybind11::detail {

template <class Tag>
struct type_caster<lancer::python::Named<Tag>> {
    PYBIND11_TYPE_CASTER(lancer::python::Named<Tag>, Tag::name);

    bool load(handle source, bool /*convert*/) {
        value.object = reinterpret_borrow<object>(source);
        return true;
    }
    static handle cast(const lancer::python::Named<Tag>& source, return_value_policy /*policy*/,
                       handle /*parent*/) {
        return source.object.inc_ref();
    }
};

}  // namespace pybind11::detail
