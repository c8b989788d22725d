// This Source Code Form is subject to the terms of the Mozilla Public
// License, v. 2.0. If a copy of the MPL was not distributed with this
// file, You can obtain one at https://mozilla.org/MPL/2.0/.
#pragma once
/// @file output_file.hpp
/// @brief An output file that appears only when complete: data goes to a temporary file
/// in the target directory, which is renamed over the target on commit(). If anything
/// fails before, the temporary file is removed and the target is left as it was.
///
/// A target that is a symbolic link is followed: the file it names is replaced and the
/// link kept. A target that is a character device or a FIFO (/dev/null, /dev/stdout, a
/// pipe) is written directly, without a temporary file (nothing can be taken back from
/// it); a block device or a socket is refused. Temporary files under way are listed in
/// a process-wide registry so that a program can remove them when it is interrupted
/// (kintsugi::remove_temporary_outputs).

#include <kintsugi/core/error.hpp>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <mutex>
#include <random>
#include <stop_token>
#include <string>
#include <string_view>
#include <system_error>
#include <type_traits>
#include <utility>
#include <vector>

namespace kintsugi::detail::io {

/// The temporary files this process is writing (created and not yet renamed or removed).
class TemporaryFiles {
public:
    /// Runs `create` (which returns whether it made the file `p`) and records `p`, under
    /// the registry's lock, so that remove_all() never misses a file it could see.
    template <class Create>
    bool create_and_add(const std::filesystem::path& p, Create&& create) {
        const std::lock_guard<std::mutex> lock(mutex_);
        if (!create()) return false;
        paths_.push_back(p);
        return true;
    }
    void forget(const std::filesystem::path& p) {
        const std::lock_guard<std::mutex> lock(mutex_);
        const auto it = std::find(paths_.begin(), paths_.end(), p);
        if (it != paths_.end()) paths_.erase(it);
    }
    /// Renames `from` to `to` and forgets `from`, under the lock (so that remove_all()
    /// does not delete a file that has just become a finished output).
    void rename(const std::filesystem::path& from, const std::filesystem::path& to, std::error_code& ec) {
        const std::lock_guard<std::mutex> lock(mutex_);
        std::filesystem::rename(from, to, ec);
        const auto it = std::find(paths_.begin(), paths_.end(), from);
        if (it != paths_.end()) paths_.erase(it);
    }
    /// Removes every recorded file; returns how many were removed.
    std::size_t remove_all() {
        const std::lock_guard<std::mutex> lock(mutex_);
        std::size_t n = 0;
        for (const auto& p : paths_) {
            std::error_code ec;
            n += std::filesystem::remove(p, ec) ? 1 : 0;
        }
        paths_.clear();
        return n;
    }

private:
    std::mutex mutex_;
    std::vector<std::filesystem::path> paths_;
};

inline TemporaryFiles& temporary_files() {
    static TemporaryFiles registry;
    return registry;
}

/// The file a write to `target` replaces: `target` with its symbolic links followed
/// (also a dangling link, whose named file is then created).
inline std::filesystem::path resolve_output_target(const std::filesystem::path& target, const std::string& name) {
    namespace fs = std::filesystem;
    fs::path p = target;
    for (int hops = 0;; ++hops) {
        std::error_code ec;
        if (!fs::is_symlink(fs::symlink_status(p, ec))) return p;
        if (hops == 40) throw io_error(name, "too many levels of symbolic links");
        const fs::path next = fs::read_symlink(p, ec);
        if (ec) throw io_error(name, "cannot read the symbolic link '" + printable(p.string()) + "': " + ec.message());
        p = next.is_absolute() ? next : p.parent_path() / next;
    }
}

/// Name of the temporary file for `filename`: ".<filename>.<8 hex>.tmp", with the name
/// shortened so that the whole stays within 255 bytes (NAME_MAX of Linux file systems).
inline std::string temporary_name(const std::string& filename, unsigned random) {
    char suffix[24];
    std::snprintf(suffix, sizeof suffix, ".%08x.tmp", random);
    constexpr std::size_t name_max = 255;
    const std::size_t keep = std::min(filename.size(), name_max - 1 - std::strlen(suffix));
    std::string name;
    name.reserve(keep + 1 + std::strlen(suffix));
    name += '.';
    name.append(filename, 0, keep);
    name += suffix;
    return name;
}

/// A renamed-later temporary file: finished and closed, waiting for its commit.
struct PendingOutput {
    std::filesystem::path temporary, target;
    std::string name;  ///< the path the caller gave (for messages)
};

class AtomicOutputFile {
public:
    /// Creates the temporary file next to `target` (next to the file a symbolic link
    /// names); throws io_error when the directory does not exist or is not writable,
    /// or when `target` is a directory, a block device or a socket. A character device
    /// or a FIFO is opened directly. `stop`: a stop request makes the next buffer
    /// flush throw io_error ("interrupted"), which removes the temporary file.
    explicit AtomicOutputFile(const std::filesystem::path& target, std::stop_token stop = {})
        : name_(target.string()), stop_(std::move(stop)) {
        namespace fs = std::filesystem;
        std::error_code ec;
        if (target.filename().empty()) throw io_error(name_, "not a file name");
        target_ = resolve_output_target(target, name_);
        if (target_.filename().string().size() > 255)
            throw io_error(name_, "the file name is " + std::to_string(target_.filename().string().size()) +
                                      " bytes long; file systems allow at most 255");
        const fs::file_status st = fs::status(target_, ec);
        if (fs::is_directory(st)) throw io_error(name_, "is a directory, cannot write a file there");
        if (fs::is_block_file(st))
            throw io_error(name_, "is a block device; refusing to write onto it (give a regular file)");
        if (fs::is_socket(st)) throw io_error(name_, "is a socket; give a regular file");
        if (fs::is_character_file(st) || fs::is_fifo(st)) {
            // Written through: /dev/null, /dev/stdout, a named pipe.
            errno = 0;
            file_ = std::fopen(target_.string().c_str(), "wb");
            if (!file_) throw io_error(name_, "cannot open for writing: " + std::generic_category().message(errno));
            direct_ = true;
            buf_.resize(kBufferSize);
            return;
        }
        std::filesystem::path dir = target_.parent_path();
        if (dir.empty()) dir = ".";
        if (!fs::is_directory(dir, ec))
            throw io_error(name_, "cannot write: directory '" + printable(dir.string()) + "' does not exist");
        std::random_device rd;
        int err = 0;
        for (int attempt = 0; attempt < 16 && !file_; ++attempt) {
            tmp_ = dir / temporary_name(target_.filename().string(), static_cast<unsigned>(rd()));
            temporary_files().create_and_add(tmp_, [&] {
                errno = 0;
                file_ = std::fopen(tmp_.string().c_str(), "wbx");
                err = errno;
                return file_ != nullptr;
            });
            if (!file_ && err != EEXIST) break;
        }
        if (!file_)
            throw io_error(name_, "cannot create a temporary file in '" + printable(dir.string()) +
                                      "': " + std::generic_category().message(err));
        // An existing file keeps its permissions.
        if (fs::is_regular_file(st)) fs::permissions(tmp_, st.permissions(), ec);
        buf_.resize(kBufferSize);
    }

    AtomicOutputFile(const AtomicOutputFile&) = delete;
    AtomicOutputFile& operator=(const AtomicOutputFile&) = delete;

    ~AtomicOutputFile() { discard(); }

    /// Returns a pointer to `n` writable bytes in the buffer (n <= 4096).
    char* reserve(std::size_t n) {
        if (pos_ + n > buf_.size()) flush_buffer();
        char* p = buf_.data() + pos_;
        pos_ += n;
        return p;
    }
    void write(const char* p, std::size_t n) {
        while (n > 0) {
            if (pos_ == buf_.size()) flush_buffer();
            const std::size_t k = std::min(n, buf_.size() - pos_);
            std::memcpy(buf_.data() + pos_, p, k);
            pos_ += k;
            p += k;
            n -= k;
        }
    }
    void write(std::string_view s) { write(s.data(), s.size()); }
    void put(char c) { *reserve(1) = c; }

    /// A double in the shortest text that reads back to the same value.
    void put_double(double v) {
        char* p = reserve(32);
        const auto r = std::to_chars(p, p + 32, v);
        pos_ -= static_cast<std::size_t>(p + 32 - r.ptr);
    }
    void put_uint(std::uint64_t v) {
        char* p = reserve(24);
        const auto r = std::to_chars(p, p + 24, v);
        pos_ -= static_cast<std::size_t>(p + 24 - r.ptr);
    }
    /// The three entries of `v` separated by spaces ("x y z"): numbers through put_double,
    /// indices through put_uint.
    template <class V>
    void put_triple(const V& v) {
        for (int c = 0; c < 3; ++c) {
            if (c) put(' ');
            if constexpr (std::is_integral_v<std::decay_t<decltype(v[0])>>)
                put_uint(v[c]);
            else
                put_double(v[c]);
        }
    }
    /// A binary value in the file's byte order (`swap` = differs from the machine's).
    template <class T>
    void put_binary(T v, bool swap) {
        char* p = reserve(sizeof(T));
        std::memcpy(p, &v, sizeof(T));
        if (swap) std::reverse(p, p + sizeof(T));
    }

    /// Flushes, closes and renames the temporary file over the target.
    void commit() {
        if (direct_) {
            close();
            committed_ = true;
            return;
        }
        PendingOutput p = finish();
        std::error_code ec;
        temporary_files().rename(p.temporary, p.target, ec);
        if (ec) {
            std::filesystem::remove(p.temporary, ec);
            throw io_error(name_, "cannot rename the temporary file into place: " + ec.message());
        }
    }

    /// Flushes and closes the temporary file and hands it over: the caller renames it
    /// (or removes it) later. A directly written target (a device) is complete here and
    /// gives an empty `temporary`.
    PendingOutput finish() {
        close();
        committed_ = true;
        return {direct_ ? std::filesystem::path() : tmp_, target_, name_};
    }

    /// Path of the temporary file (for tests).
    [[nodiscard]] const std::filesystem::path& temporary_path() const { return tmp_; }
    /// Whether the target is written directly (a character device or a FIFO).
    [[nodiscard]] bool direct() const { return direct_; }

private:
    static constexpr std::size_t kBufferSize = std::size_t{1} << 20;

    void close() {
        flush_buffer();
        std::FILE* f = file_;
        file_ = nullptr;
        if (std::fflush(f) != 0) {
            const int err = errno;
            std::fclose(f);
            remove_tmp();
            throw io_error(name_, "write error: " + std::generic_category().message(err));
        }
        if (std::fclose(f) != 0) {
            const int err = errno;
            remove_tmp();
            throw io_error(name_, "write error on close: " + std::generic_category().message(err));
        }
    }
    void flush_buffer() {
        if (stop_.stop_requested()) {
            discard();
            committed_ = true;  // nothing left to clean up
            throw io_error(name_, "interrupted; the file was not written");
        }
        if (pos_ == 0) return;
        if (!file_) throw io_error(name_, "write after close");
        if (std::fwrite(buf_.data(), 1, pos_, file_) != pos_) {
            const int err = errno;
            std::fclose(file_);
            file_ = nullptr;
            remove_tmp();
            throw io_error(name_, "write error: " + std::generic_category().message(err));
        }
        pos_ = 0;
    }
    void remove_tmp() {
        if (direct_ || tmp_.empty()) return;
        std::error_code ec;
        std::filesystem::remove(tmp_, ec);
        temporary_files().forget(tmp_);
    }
    void discard() noexcept {
        if (committed_) return;
        if (file_) {
            std::fclose(file_);
            file_ = nullptr;
        }
        remove_tmp();
    }

    std::filesystem::path target_;
    std::string name_;
    std::stop_token stop_;
    std::filesystem::path tmp_;
    std::FILE* file_ = nullptr;
    std::vector<char> buf_;
    std::size_t pos_ = 0;
    bool committed_ = false;
    bool direct_ = false;
};

}  // namespace kintsugi::detail::io
