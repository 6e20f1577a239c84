#pragma once
// The one list of an options struct's fields, by name. Next to each options
// struct (TrackerOptions, LocalMapperOptions, LoopCloserOptions and the ones
// nested in them) a function found by argument-dependent lookup,
//
//   template <class F> void option_fields(const Options*, F&& f);
//
// calls f(name, &Options::member) once per field a user may set: numbers,
// flags, and nested option structs (which have their own list). The Python
// bindings (def_readwrite per field) and the ROS node (~tracker/NAME,
// ~mapping/NAME, ~loop/NAME parameters) walk these lists, so a field added to
// a list reaches both under the same name.
#include <type_traits>

namespace dynaorb {

namespace detail {
struct AnyOptionField {
  template <class Member>
  void operator()(const char*, Member) const {}
};
}  // namespace detail

// true for an options struct with an option_fields list.
template <class T, class = void>
struct has_option_fields : std::false_type {};
template <class T>
struct has_option_fields<T, std::void_t<decltype(option_fields(static_cast<const T*>(nullptr),
                                                               detail::AnyOptionField{}))>> : std::true_type {};
template <class T>
inline constexpr bool has_option_fields_v = has_option_fields<T>::value;

// f(name, &Options::member) for each field of Options' list.
template <class Options, class F>
void for_each_option_field(F&& f) {
  option_fields(static_cast<const Options*>(nullptr), f);
}

}  // namespace dynaorb
