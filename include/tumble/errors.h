#pragma once
// The errors Tumble throws for bad input, shared by the engine and the embedding API (tumble/sandbox.h):
// their messages are the command line's, which prints what() after "tumble: ".

#include <cstdint>
#include <stdexcept>
#include <string>

namespace tumble {

/// A problem in a scenario or its overrides; what() is "file:line:col: what is wrong".
class ScenarioError : public std::runtime_error {
public:
    ScenarioError(std::string file, int line, int column, const std::string& message);

    const std::string& file() const { return m_file; }
    int line() const { return m_line; }     ///< 0 when unknown
    int column() const { return m_column; } ///< 0 when unknown
    const std::string& message() const { return m_message; }

private:
    std::string m_file;
    int m_line;
    int m_column;
    std::string m_message;
};

/// A replay file that cannot be read: the message names the file and the byte offset.
class ReplayError : public std::runtime_error {
public:
    ReplayError(const std::string& file, std::uint64_t offset, const std::string& message);
};

} // namespace tumble
