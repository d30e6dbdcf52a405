"""The thesis' rate-bounded LPV synthesis (not flown; docs/LPV_SYNTHESIS.md).

weights and interconnection build the weighted generalised plant on the thesis' grid;
lpv_synthesis solves the parameter-dependent LMIs (cvxpy with Clarabel, or the project's own
interior-point solver sdp_ipm); certificate, reconstruction and verification check the result;
pipeline runs the whole path and exports the table ``vega synth`` writes.
"""
