// Reading one nodding pass from its PCD file (docs/data_contract.md "Input 1"): the PCD reader
// (pcdp/io/pcd.hpp) plus the contract's checks, to a pcdp::Pass (pcdp/core/pass.hpp). Declared in
// namespace pcdp (not pcdp::io): a pass is the core's type; callers write pcdp::read_pass.
#pragma once

#include <cstddef>
#include <string>

#include "pcdp/core/pass.hpp"
#include "pcdp/io/pcd.hpp"

namespace pcdp {

/// Builds a pass from a PCD table, checking the data contract: required fields and their types,
/// finite values, non-negative ranges, one nod reading per line, stamps increasing along each
/// line and from line to line, unique (line, beam). Throws InputError naming the file, the field
/// and the line/beam of the first offence.
Pass pass_from_table(io::PcdTable&& table, const std::string& source, std::size_t index);

/// The cheap part of read_pass, for checking every pass before the heavy work: the file is a
/// regular, readable file, its header parses, has the required fields with their types, and
/// (binary) the data it claims fits in the file. Reads the header only. Throws InputError.
void check_pass_header(const std::string& path);

/// read_pcd + pass_from_table.
Pass read_pass(const std::string& path, std::size_t index);

}  // namespace pcdp
