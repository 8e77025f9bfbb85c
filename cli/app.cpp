#include "cli/app.h"

#include <tbb/global_control.h>

#include <cstdio>
#include <cstdlib>
#include <exception>
#include <memory>
#include <new>
#include <string>
#include <system_error>

#include "cli/arguments.h"
#include "common/atomic_file.h"
#include "common/error.h"
#include "common/input_file.h"

namespace distile::cli {

namespace {

/// `message` on one line: line breaks and other control characters become spaces, so an error
/// is always exactly one line on stderr.
std::string oneLine(std::string message) {
    for (char& c : message) {
        if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f) c = ' ';
    }
    return message;
}

/// The option named `name` (e.g. "--epsilon") of `command` or of any command or option group
/// under it, or null.
const CLI::Option* findOption(const CLI::App& command, const std::string& name) {
    for (const CLI::Option* option : command.get_options()) {
        for (const std::string& longName : option->get_lnames())
            if ("--" + longName == name) return option;
    }
    for (const CLI::App* under : command.get_subcommands({}))
        if (const CLI::Option* found = findOption(*under, name)) return found;
    return nullptr;
}

/// CLI11's message for a value it could not convert ("Could not convert: --epsilon = abc") in
/// the form of distile's others: the option, the value and what it takes. Other messages as
/// they are.
std::string parseErrorMessage(const CLI::App& app, const CLI::ParseError& error) {
    const std::string message = error.what();
    const std::string prefix = "Could not convert: ";
    const std::size_t equals = message.find(" = ");
    if (!dynamic_cast<const CLI::ConversionError*>(&error) || message.rfind(prefix, 0) != 0 ||
        equals == std::string::npos)
        return message;
    const std::string name = message.substr(prefix.size(), equals - prefix.size());
    const std::string value = message.substr(equals + 3);
    const CLI::Option* option = findOption(app, name);
    const std::string type = option ? option->get_type_name() : "";
    const bool several = option && option->get_items_expected_max() > 1;
    std::string wanted = "see the accepted values";
    if (type.starts_with("INT"))
        wanted = several ? "give integers" : "give an integer";
    else if (type.starts_with("UINT"))
        wanted = several ? "give whole numbers" : "give a whole number";
    else if (type.starts_with("FLOAT"))
        wanted = several ? "give numbers" : "give a number";
    return name + ": '" + value + "' is not accepted; " + wanted;
}

int parseAndRun(int argc, char** argv, const std::function<void(CLI::App&)>& addCommands) {
    CLI::App app{
        "distile: volumetric distance detail. Bakes detail (chain mail, ...) into exact, periodic "
        "distance tiles\n"
        "(OpenVDB level set -> 256x256x16 EXR atlas) and renders them on base meshes with a CPU "
        "sphere tracer.\n"};
    app.name("distile");
    app.footer(kExitStatusHelp);
    app.require_subcommand(1);
    app.fallthrough();  // --threads may also follow the subcommand
    app.set_version_flag("--version", "distile 0.1.0");
    int threads = 0;
    app.add_option("--threads", threads, "Worker threads (default: all cores)")
        ->check(integerRange(1, 1024));
    // The thread limit must be in force before a command's callback runs.
    std::unique_ptr<tbb::global_control> threadLimit;
    app.parse_complete_callback([&] {
        if (threads > 0) {
            threadLimit = std::make_unique<tbb::global_control>(
                tbb::global_control::max_allowed_parallelism, std::size_t(threads));
        }
    });
    addCommands(app);
    try {
        app.parse(argc, argv);
    } catch (const CLI::Success& success) {  // --help, --version
        return app.exit(success);
    } catch (const CLI::ParseError& error) {
        // No command: CLI11 says only that one is required, not which word it did not take.
        if (app.get_subcommands().empty() &&
            (!app.remaining().empty() || dynamic_cast<const CLI::RequiredError*>(&error))) {
            std::string commands;
            for (const CLI::App* command : app.get_subcommands({}))
                commands += (commands.empty() ? "" : ", ") + command->get_name();
            const std::string word = app.remaining().empty() ? "" : app.remaining().front();
            const std::string what = word.empty()          ? std::string("a command is required")
                                     : word.front() == '-' ? "'" + word + "' is not an option"
                                                           : "'" + word + "' is not a command";
            std::fprintf(stderr, "distile: error: %s; commands: %s (see distile --help)\n",
                         oneLine(what).c_str(), commands.c_str());
            return kExitInput;
        }
        // The help of the command whose options were being read, if one was (option groups are
        // unnamed apps of their own), unless the error is about distile's own option (--threads,
        // which may follow a command but is listed in distile --help).
        std::string help = "distile";
        const std::string message = error.what();
        bool aboutOwnOption = false;
        for (const CLI::Option* option : app.get_options()) {
            for (const std::string& name : option->get_lnames())
                aboutOwnOption = aboutOwnOption || message.rfind("--" + name + ":", 0) == 0;
        }
        const auto parsed = [](const CLI::App* command) { return command->parsed(); };
        for (std::vector<CLI::App*> read = app.get_subcommands(parsed);
             !aboutOwnOption && !read.empty(); read = read.front()->get_subcommands(parsed)) {
            if (!read.front()->get_name().empty()) help += " " + read.front()->get_name();
        }
        std::fprintf(stderr, "distile: error: %s (see %s --help)\n",
                     oneLine(parseErrorMessage(app, error)).c_str(), help.c_str());
        return kExitInput;
    }
    return 0;
}

}  // namespace

namespace {

/// The last resort when an exception escapes where none may (a destructor or a noexcept function
/// in a library, while another unwinds): one line and the exit status its kind calls for, not
/// an abort.
[[noreturn]] void terminateInOneLine() {
    int status = kExitBug;
    std::string message = "internal failure: an exception escaped a library (a bug)";
    try {
        if (const std::exception_ptr escaped = std::current_exception())
            std::rethrow_exception(escaped);
    } catch (const std::bad_alloc&) {
        status = kExitInput;
        message = "out of memory: the input or options need more memory than there is";
    } catch (const std::exception& error) {
        message += std::string(" (") + error.what() + ")";
    } catch (...) {
    }
    std::fprintf(stderr, "distile: error: %s\n", oneLine(message).c_str());
    std::fflush(stderr);
    std::_Exit(status);
}

}  // namespace

int runCommandLine(int argc, char** argv, const std::function<void(CLI::App&)>& addCommands) {
    std::set_terminate(terminateInOneLine);
    recordInputFiles();           // no output may replace one of the command's inputs
    removeTemporariesOnSignal();  // Ctrl-C leaves no partial file
    const auto fail = [](int status, const std::string& message) {
        std::fprintf(stderr, "distile: error: %s\n", oneLine(message).c_str());
        return status;
    };
    try {
        return parseAndRun(argc, argv, addCommands);
    } catch (const InputError& error) {
        return fail(kExitInput, error.what());
    } catch (const FormatError& error) {
        return fail(kExitInput, error.what());
    } catch (const std::bad_alloc&) {
        return fail(kExitInput,
                    "out of memory: the input or options need more memory than there is; use "
                    "smaller sizes, bands or sample counts");
    } catch (const std::system_error& error) {  // a write refused by the system (disk full, ...)
        return fail(kExitInput, error.what());
    } catch (const InternalError& error) {
        return fail(kExitBug, std::string(error.what()) + " (internal failure)");
    } catch (const std::exception& error) {
        return fail(kExitBug, std::string(error.what()) +
                                  " (internal failure: an unexpected error, a bug in distile)");
    } catch (...) {
        return fail(kExitBug, "internal failure: an unknown exception, a bug in distile");
    }
}

}  // namespace distile::cli
