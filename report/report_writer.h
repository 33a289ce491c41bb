#pragma once

// The audit report written: the document built from the pipeline's outputs and the job,
// laid out as report.html (with the 3D view of the model) and report.pdf in one folder.

#include <filesystem>
#include <functional>
#include <string>

#include "report/html_report.h"
#include "report/pdf_report.h"
#include "report/report_model.h"
#include "report/viewer_embed.h"

namespace hw::report {

struct ReportWriteOptions {
  bool html = true;        // write report.html
  bool pdf = true;         // write report.pdf
  bool model_view = true;  // the HTML's interactive 3D view (needs ReportInputs::model_ply)
  PdfOptions pdf_options;
  ViewerOptions viewer;

  // "" or "field: must ..., got ..." (nested options prefixed "pdf." / "viewer.").
  std::string Check() const;
};

struct ReportWriteResult {
  std::filesystem::path html_path, pdf_path;  // empty when not written
  HtmlStats html;
  PdfStats pdf;
  ViewerStats viewer;
  int spots = 0;
  std::vector<std::pair<std::string, int>> spots_by_severity;  // most severe first
  double seconds = 0;
};

// Builds the document (BuildDocument) and writes out_folder/report.html and report.pdf,
// each atomically, holding the folder's run lock (core/output_folder.h). Every input is
// read (and every figure decoded) before anything is written: a bad input leaves the
// folder as it was; existing report files are replaced (the caller decides whether that is
// allowed). `progress(done, total)` after each step. Throws core::InputError (inputs),
// core::OutputError (out_folder unwritable or a file). Asserts options.Check() == "".
ReportWriteResult WriteReport(const ReportInputs& inputs, const std::filesystem::path& out_folder,
                              const ReportWriteOptions& options,
                              const std::function<void(int done, int total)>& progress = nullptr);

}  // namespace hw::report
