#pragma once
// How much memory one step may hold before it is refused rather than run:
// half the machine's physical memory, and at least 4 GB.

#include <algorithm>

#include <unistd.h>

namespace curvenet::detail {

inline double memory_budget() {
  const long pages = ::sysconf(_SC_PHYS_PAGES), page = ::sysconf(_SC_PAGE_SIZE);
  const double physical = pages > 0 && page > 0 ? static_cast<double>(pages) * static_cast<double>(page) : 0.0;
  return std::max(4e9, physical / 2);
}

} // namespace curvenet::detail
