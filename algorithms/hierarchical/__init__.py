"""The paper's hierarchical method (Sec. III): robot groups exchanging messages over lossy
links, a GRU that predicts the lost ones, a finite reference policy conditioning each
group's local joint-control policy, and the predictive safety filter (Algorithm 1)."""
