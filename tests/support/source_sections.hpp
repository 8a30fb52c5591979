#pragma once
// Tests that adjust a loaded configuration's backend section in place.
#include <memory>
#include <string>

#include "exodaq/drivers/backend.hpp"

namespace exodaq::test {

// A private, editable copy of a backend's section (its defaults when the file
// has none), put back into `options`.
template <typename T>
T& edit_section(drivers::SourceOptions& options, const std::string& name) {
  auto copy = std::make_shared<T>();
  if (const T* current = options.section_as<T>(name)) *copy = *current;
  T& ref = *copy;
  options.sections[name] = std::move(copy);
  return ref;
}

}  // namespace exodaq::test
