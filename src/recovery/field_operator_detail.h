#pragma once
// Internal: FieldOperator's (recover.h) single-precision products on its pixel box, for stages
// other than the field retrieval that evaluate the field model (recover_field_model.h).
#include <Eigen/Dense>
#include <complex>
#include <vector>

#include "wavebrdf/recover.h"

namespace wavebrdf::detail {

// The operator's field without the diagonal phases Φx, Φy (they change no |Ψ| and cancel in
// the adjoint of a loss of |Ψ|) on its pixel box, from the object (the operator's fine grid,
// row-major).
void field_forward_unphased(const FieldOperator& op, const std::complex<double>* object, Eigen::MatrixXcf& psi);
// object += the adjoint of field_forward_unphased applied to g (on the box); writes only the
// samples of field_rows × field_cols.
void field_adjoint_unphased_add(const FieldOperator& op, const Eigen::MatrixXcf& g, std::complex<double>* object);
// The box: slice pixels [first_row, first_row + box.rows()) × [first_col, …), √c1 on it.
const Eigen::MatrixXd& field_amplitude_box(const FieldOperator& op, int& first_row, int& first_col);
// The fine-grid rows / columns the footprint covers (each once).
const std::vector<int>& field_rows(const FieldOperator& op);
const std::vector<int>& field_cols(const FieldOperator& op);

}  // namespace wavebrdf::detail
