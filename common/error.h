/// @file
/// The exception types distile throws: two for bad input, which every entry point checks, one
/// for an output the system refused, and one for bugs. Messages name the file or field, the bad
/// value and what is accepted, in one line, so the command can print them as they are.
#pragma once

#include <cerrno>
#include <charconv>
#include <initializer_list>
#include <stdexcept>
#include <string>
#include <string_view>
#include <system_error>
#include <type_traits>
#include <utility>

namespace distile {

/// A value the caller passed (a size, a parameter, a path, a scene field) is not acceptable.
///
/// Libraries name the field of their own options struct
/// (`InputError::inField("march.epsilonTexels", "0 is not accepted; ...")`); a program that filled
/// the struct from its own input (a command-line flag, a JSON path) shows the error under that name
/// with `renamed`.
class InputError : public std::runtime_error {
  public:
    using std::runtime_error::runtime_error;

    /// An error about one field, as the options struct names it (member path, e.g.
    /// "march.epsilonTexels"): what() reads "field: problem".
    static InputError inField(std::string field, std::string problem) {
        InputError error(field + ": " + problem);
        error.field_ = std::move(field);
        error.problem_ = std::move(problem);
        return error;
    }

    /// The field this error is about; empty when it is not about one field.
    const std::string& field() const noexcept { return field_; }

    /// The message without the field's name (the whole message when there is no field).
    std::string problem() const { return field_.empty() ? what() : problem_; }

    /// The same error about `shownAs` (a flag, a JSON path) instead of the field.
    InputError renamed(std::string shownAs) const { return inField(std::move(shownAs), problem()); }

  private:
    std::string field_;
    std::string problem_;
};

/// A field as a library names it (an options member, "march.epsilonTexels") and the name a
/// program shows it under (the flag or keyword that filled it, "--epsilon").
struct ShownName {
    std::string_view field;
    std::string_view shownAs;
};

/// `error` under the name `names` gives its field, so the user reads the name they typed; as it
/// is when its field is not among `names`.
inline InputError shownUnder(const InputError& error, std::initializer_list<ShownName> names) {
    for (const ShownName& name : names) {
        if (!error.field().empty() && error.field() == name.field)
            return error.renamed(std::string(name.shownAs));
    }
    return error;
}

/// `value` as messages show a number: the shortest text that reads back as the same value ("2",
/// "0.1", "1e+30"), not std::to_string's six decimals ("2.000000", "0.000000" for 1e-7). A float
/// is shown as the float it is ("0.1", not 0.1f widened to "0.10000000149011612").
template <typename Number>
std::string numberText(Number value) {
    static_assert(std::is_floating_point_v<Number>, "integers: std::to_string");
    char text[32];
    const auto end = std::to_chars(text, text + sizeof text, value).ptr;
    return std::string(text, end);
}

/// A file exists but its contents are not what distile reads (truncated, corrupted, wrong kind).
struct FormatError : std::runtime_error {
    using std::runtime_error::runtime_error;
};

/// An output file the system would not let distile write (the disk is full, a quota, an I/O
/// error): neither bad input nor a bug. A std::system_error, as the system's other refusals are
/// (programs report it as refused input and leave nothing written; Python raises OSError); its
/// message names the file as the user gave it and says why.
class WriteError : public std::system_error {
  public:
    explicit WriteError(std::string message)
        : std::system_error(EIO, std::generic_category()), message_(std::move(message)) {}
    const char* what() const noexcept override { return message_.c_str(); }

  private:
    std::string message_;
};

/// A broken invariant: distile computed something it never should (a NaN pixel from valid
/// input). Not the user's fault; the message says so and the command exits with its own status.
struct InternalError : std::logic_error {
    using std::logic_error::logic_error;
};

}  // namespace distile
